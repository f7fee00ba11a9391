"""Lane vectors for the compiled kernels: several scenarios in one call, one SIMD register per quantity.

A kernel written once runs either on ``float64`` scalars (one scenario) or on :class:`Lanes` (``width``
scenarios at once, one per lane). ``Lanes`` is a numba type held as an LLVM ``<width x double>``: its
``+ - * /``, unary ``-``, ``abs`` and :func:`vsqrt` are single packed instructions (``vaddpd``, ``vmulpd``,
``vdivpd``, ``vsqrtpd`` on ``ymm``/``zmm`` registers), each an IEEE operation on every lane, so every lane
gets the same bits as the same arithmetic on scalars: no reassociation, no contraction into fused
multiply-adds (neither form carries fast-math flags; ``tests/test_lanes.py`` checks the machine code and the
bits). Comparisons give a :class:`LaneMask`; a branch that differs between lanes is written with
:func:`select` (both sides computed, one kept per lane) or with a per-lane loop over :func:`lane` and
:func:`set_lane`. Functions that have no exact vector form (``sin``, ``exp``...: :func:`vsin`, :func:`vexp`,
...) call the same libm function once per lane.

Every helper below also accepts scalars (``float``, ``bool``), where it is the obvious scalar operation, so
one source compiles to both forms. An array of lane vectors is a ``float64`` array whose last axis holds the
lanes, passed to a kernel as :class:`LaneArray`: indexing it gives a ``Lanes`` value, assigning one stores it.

numba's cache keys a compiled function on its own source file only: after a change here, the kernels' cached
machine code (``helpers/virtual/__pycache__/*.nbi``, ``*.nbc``) must be cleared to take it up.

Why not numba's own vectorisation: LLVM's loop vectoriser gives up on a loop that writes several arrays it
cannot prove apart (it would need run-time overlap checks beyond its budget), and numba leaves LLVM's SLP
vectoriser off (``NUMBA_SLP_VECTORIZE=0``, since a miscompilation reported upstream as numba/numba#8705).
Explicit vector types need neither pass and compile the same on every setting of both.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.boxing import unbox_array
from numba.core.imputils import lower_builtin, lower_cast
from numba.core.typing.templates import AbstractTemplate, infer_global, signature
from numba.extending import models, register_model, unbox

__all__ = [
    "Lanes", "LaneMask", "LaneArray", "select", "any_lane", "all_lane", "lnot", "lane", "set_lane",
    "lane_count", "vsqrt", "vsin", "vcos", "vexp", "vtanh", "vatan2",
]  # fmt: skip


class Lanes(types.Type):
    """``width`` doubles, one per scenario (numba type; an LLVM ``<width x double>``)."""

    def __init__(self, width: int) -> None:
        self.width = int(width)
        super().__init__(name=f"Lanes{self.width}")

    def unify(self, typingctx, other):  # noqa: ANN001, ANN201 - numba's protocol
        """A variable holding a scalar in one branch and lanes in another holds lanes (scalars broadcast)."""
        if isinstance(other, types.Float | types.Integer):
            return self
        return None

    def can_convert_from(self, typingctx, other):  # noqa: ANN001, ANN201 - numba's protocol
        """A scalar converts to lanes by broadcasting."""
        if isinstance(other, types.Float | types.Integer):
            return types.Conversion.safe
        return None


class LaneMask(types.Type):
    """One boolean per lane (numba type; an LLVM ``<width x i1>``)."""

    def __init__(self, width: int) -> None:
        self.width = int(width)
        super().__init__(name=f"LaneMask{self.width}")


@register_model(Lanes)
class _LanesModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):  # noqa: ANN001 - numba's protocol
        super().__init__(dmm, fe_type, ir.VectorType(ir.DoubleType(), fe_type.width))


@register_model(LaneMask)
class _LaneMaskModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):  # noqa: ANN001 - numba's protocol
        super().__init__(dmm, fe_type, ir.VectorType(ir.IntType(1), fe_type.width))


class LaneArrayType(types.Array):
    """The numba type of a :class:`LaneArray`: a C-ordered array of :class:`Lanes` (unaligned loads)."""

    def __init__(self, width: int, ndim: int) -> None:
        super().__init__(Lanes(width), ndim, "C", aligned=False, name=f"LaneArray({width}, {ndim}d)")


register_model(LaneArrayType)(models.ArrayModel)


@lower_cast(LaneArrayType, types.Array)
def _lane_array_as_array(context, builder, fromty, toty, val):  # noqa: ANN001, ANN202 - numba's protocol
    """A lane array is an array of lanes (the same data model): where the two meet, nothing to convert."""
    return val


class LaneArray:
    """A ``float64`` array whose last axis holds the lanes, as a kernel sees it: an array of :class:`Lanes`.

    Parameters
    ----------
    data : numpy.ndarray
        C-contiguous ``float64``, shape ``(..., width)``; the kernel reads and writes it in place.
    """

    def __init__(self, data: npt.NDArray[np.float64]) -> None:
        if not (isinstance(data, np.ndarray) and data.dtype == np.float64 and data.flags.c_contiguous
                and data.ndim >= 2):  # fmt: skip
            raise ValueError("a LaneArray needs a C-contiguous float64 array of at least two dimensions")
        self.data = data
        width = data.shape[-1]
        self._records = data.view(np.dtype([("lanes", np.float64, (width,))])).reshape(data.shape[:-1])
        self._numba_type_ = LaneArrayType(width, data.ndim - 1)

    @property
    def width(self) -> int:
        """Lanes."""
        return int(self.data.shape[-1])


@unbox(LaneArrayType)
def _unbox_lane_array(typ, obj, c):  # noqa: ANN001, ANN202 - numba's protocol
    records = c.pyapi.object_getattr_string(obj, "_records")
    native = unbox_array(types.Array(typ.dtype, typ.ndim, "C", aligned=False), records, c)
    c.pyapi.decref(records)
    return native


# ---- code generation -------------------------------------------------------------------------------------
def _vector_intrinsic(builder: ir.IRBuilder, name: str, ret: ir.Type, args: list) -> ir.Value:
    """Call the LLVM intrinsic ``name`` overloaded on the first argument's vector type."""
    vt = args[0].type
    elem = "f64" if isinstance(vt.element, ir.DoubleType) else f"i{vt.element.width}"
    fnty = ir.FunctionType(ret, [a.type for a in args])
    fn = cgutils.get_or_insert_function(builder.module, fnty, f"{name}.v{vt.count}{elem}")
    return builder.call(fn, args)


@lower_cast(types.Float, Lanes)
@lower_cast(types.Integer, Lanes)
def _broadcast(context, builder, fromty, toty, val):  # noqa: ANN001, ANN202 - numba's protocol
    val = context.cast(builder, val, fromty, types.float64)
    vt = ir.VectorType(ir.DoubleType(), toty.width)
    one = builder.insert_element(ir.Constant(vt, ir.Undefined), val, ir.Constant(ir.IntType(32), 0))
    zeros = ir.Constant(ir.VectorType(ir.IntType(32), toty.width), [0] * toty.width)
    return builder.shuffle_vector(one, one, zeros)


def _scalar(t: types.Type) -> bool:
    return isinstance(t, types.Float | types.Integer)


def _operands(args: tuple) -> Lanes | None:
    """The lanes type of a binary operation on lanes (and a scalar), or None."""
    if len(args) != 2:
        return None
    a, b = args
    if isinstance(a, Lanes) and (b == a or _scalar(b)):
        return a
    if isinstance(b, Lanes) and _scalar(a):
        return b
    return None


def _arithmetic(op: Callable, emit: Callable) -> None:
    @infer_global(op)
    class _Typing(AbstractTemplate):
        def generic(self, args, kws):  # noqa: ANN001, ANN202 - numba's protocol
            t = _operands(args)
            return None if t is None else signature(t, t, t)

    @lower_builtin(op, Lanes, Lanes)
    def _lower(context, builder, sig, args):  # noqa: ANN001, ANN202 - numba's protocol
        return emit(builder, args[0], args[1])


for _ops, _emit in (
    ((operator.add, operator.iadd), lambda b, x, y: b.fadd(x, y)),
    ((operator.sub, operator.isub), lambda b, x, y: b.fsub(x, y)),
    ((operator.mul, operator.imul), lambda b, x, y: b.fmul(x, y)),
    ((operator.truediv, operator.itruediv), lambda b, x, y: b.fdiv(x, y)),
):
    for _op in _ops:
        _arithmetic(_op, _emit)


def _comparison(op: Callable, code: str) -> None:
    @infer_global(op)
    class _Typing(AbstractTemplate):
        def generic(self, args, kws):  # noqa: ANN001, ANN202 - numba's protocol
            t = _operands(args)
            return None if t is None else signature(LaneMask(t.width), t, t)

    @lower_builtin(op, Lanes, Lanes)
    def _lower(context, builder, sig, args):  # noqa: ANN001, ANN202 - numba's protocol
        if code == "!=":  # as numba compares floats: true when either is NaN
            return builder.fcmp_unordered("!=", args[0], args[1])
        return builder.fcmp_ordered(code, args[0], args[1])


for _op, _code in ((operator.lt, "<"), (operator.le, "<="), (operator.gt, ">"), (operator.ge, ">="),
                   (operator.eq, "=="), (operator.ne, "!=")):  # fmt: skip
    _comparison(_op, _code)


def _mask_logic(op: Callable, emit: Callable) -> None:
    @infer_global(op)
    class _Typing(AbstractTemplate):
        def generic(self, args, kws):  # noqa: ANN001, ANN202 - numba's protocol
            if len(args) == 2 and isinstance(args[0], LaneMask) and args[1] == args[0]:
                return signature(args[0], args[0], args[0])
            return None

    @lower_builtin(op, LaneMask, LaneMask)
    def _lower(context, builder, sig, args):  # noqa: ANN001, ANN202 - numba's protocol
        return emit(builder, args[0], args[1])


for _ops, _emit in (
    ((operator.and_, operator.iand), lambda b, x, y: b.and_(x, y)),
    ((operator.or_, operator.ior), lambda b, x, y: b.or_(x, y)),
    ((operator.xor, operator.ixor), lambda b, x, y: b.xor(x, y)),
):
    for _op in _ops:
        _mask_logic(_op, _emit)


def _unary(op: Callable, kind: type, emit: Callable) -> None:
    @infer_global(op)
    class _Typing(AbstractTemplate):
        def generic(self, args, kws):  # noqa: ANN001, ANN202 - numba's protocol
            if len(args) == 1 and isinstance(args[0], kind):
                return signature(args[0], args[0])
            return None

    @lower_builtin(op, kind)
    def _lower(context, builder, sig, args):  # noqa: ANN001, ANN202 - numba's protocol
        return emit(builder, args[0])


_unary(operator.neg, Lanes, lambda b, x: b.fneg(x))
_unary(operator.pos, Lanes, lambda b, x: x)
_unary(abs, Lanes, lambda b, x: _vector_intrinsic(b, "llvm.fabs", x.type, [x]))
_unary(operator.invert, LaneMask, lambda b, x: b.not_(x))


# ---- helpers for code that compiles to either form ---------------------------------------------------------
# Each is typed and lowered directly (no numba function of its own to compile per use), scalars included.
def select(mask, a, b):  # noqa: ANN001, ANN201 - compiled code only (typed and lowered below)
    """``a`` where ``mask`` holds, else ``b``, per lane (scalars: ``a if mask else b``)."""
    raise NotImplementedError("compiled code only")


def any_lane(mask):  # noqa: ANN001, ANN201
    """Whether ``mask`` holds in some lane (a ``bool``: itself)."""
    raise NotImplementedError("compiled code only")


def all_lane(mask):  # noqa: ANN001, ANN201
    """Whether ``mask`` holds in every lane (a ``bool``: itself)."""
    raise NotImplementedError("compiled code only")


def lnot(mask):  # noqa: ANN001, ANN201
    """Not ``mask``, per lane (``~`` would be an integer's complement on a ``bool``)."""
    raise NotImplementedError("compiled code only")


def lane(v, k):  # noqa: ANN001, ANN201
    """Lane ``k`` of ``v`` (a scalar: itself)."""
    raise NotImplementedError("compiled code only")


def set_lane(v, k, x):  # noqa: ANN001, ANN201
    """``v`` with lane ``k`` replaced by ``x`` (a scalar: ``x``)."""
    raise NotImplementedError("compiled code only")


def lane_count(v):  # noqa: ANN001, ANN201
    """The number of lanes of ``v`` (a compile-time constant; a scalar: 1)."""
    raise NotImplementedError("compiled code only")


def vsqrt(x):  # noqa: ANN001, ANN201
    """Square root, per lane (correctly rounded: ``vsqrtpd`` gives ``math.sqrt``'s bits)."""
    raise NotImplementedError("compiled code only")


def vsin(x):  # noqa: ANN001, ANN201
    """``math.sin`` of every lane (one libm call per lane: its bits)."""
    raise NotImplementedError("compiled code only")


def vcos(x):  # noqa: ANN001, ANN201
    """``math.cos`` of every lane (one libm call per lane)."""
    raise NotImplementedError("compiled code only")


def vexp(x):  # noqa: ANN001, ANN201
    """``math.exp`` of every lane (one libm call per lane)."""
    raise NotImplementedError("compiled code only")


def vtanh(x):  # noqa: ANN001, ANN201
    """``math.tanh`` of every lane (one libm call per lane)."""
    raise NotImplementedError("compiled code only")


def vatan2(y, x):  # noqa: ANN001, ANN201
    """``math.atan2`` of every lane (one libm call per lane)."""
    raise NotImplementedError("compiled code only")


def _register(fn: Callable, typer: Callable, lower: Callable) -> None:
    """Type ``fn`` with ``typer(*argtypes) -> signature or None`` and lower it with ``lower``."""

    @infer_global(fn)
    class _Typing(AbstractTemplate):
        def generic(self, args, kws):  # noqa: ANN001, ANN202 - numba's protocol
            return None if kws else typer(*args)

    lower_builtin(fn, types.VarArg(types.Any))(lower)


def _value_type(*ts: types.Type) -> types.Type | None:
    """Lanes if any of ``ts`` is (of one width), else float64 for scalars; None otherwise."""
    widths = {t.width for t in ts if isinstance(t, Lanes | LaneMask)}
    if len(widths) > 1 or not all(isinstance(t, Lanes | LaneMask) or _scalar(t) for t in ts):
        return None
    return Lanes(widths.pop()) if widths else types.float64


def _type_select(mask, a, b):  # noqa: ANN001, ANN202
    if not isinstance(mask, LaneMask | types.Boolean) or isinstance(a, LaneMask) or isinstance(b, LaneMask):
        return None
    out = _value_type(mask, a, b) if isinstance(mask, LaneMask) else _value_type(a, b)
    return None if out is None else signature(out, mask, a, b)


def _lower_select(context, builder, sig, args):  # noqa: ANN001, ANN202
    out = sig.return_type
    a = context.cast(builder, args[1], sig.args[1], out)
    b = context.cast(builder, args[2], sig.args[2], out)
    return builder.select(args[0], a, b)


_register(select, _type_select, _lower_select)


def _type_mask(result: types.Type) -> Callable:
    def typer(mask=None, *rest):  # noqa: ANN001, ANN202
        if rest or not isinstance(mask, LaneMask | types.Boolean):
            return None
        return signature(mask if result is None else result, mask)

    return typer


def _lower_reduce(name: str) -> Callable:
    def lower(context, builder, sig, args):  # noqa: ANN001, ANN202
        if isinstance(sig.args[0], types.Boolean):
            return args[0]
        return _vector_intrinsic(builder, f"llvm.vector.reduce.{name}", ir.IntType(1), [args[0]])

    return lower


_register(any_lane, _type_mask(types.boolean), _lower_reduce("or"))
_register(all_lane, _type_mask(types.boolean), _lower_reduce("and"))
_register(lnot, _type_mask(None), lambda context, builder, sig, args: builder.not_(args[0]))


def _type_lane(v=None, k=None, *rest):  # noqa: ANN001, ANN202
    if rest or not isinstance(k, types.Integer):
        return None
    if isinstance(v, Lanes):
        return signature(types.float64, v, k)
    if isinstance(v, LaneMask):
        return signature(types.boolean, v, k)
    return signature(v, v, k) if isinstance(v, types.Float | types.Boolean | types.Integer) else None


def _lower_lane(context, builder, sig, args):  # noqa: ANN001, ANN202
    if isinstance(sig.args[0], Lanes | LaneMask):
        return builder.extract_element(args[0], args[1])
    return args[0]


_register(lane, _type_lane, _lower_lane)


def _type_set_lane(v=None, k=None, x=None, *rest):  # noqa: ANN001, ANN202
    if rest or not isinstance(k, types.Integer) or not _scalar(x):
        return None
    if isinstance(v, Lanes):
        return signature(v, v, k, x)
    return signature(types.float64, v, k, x) if isinstance(v, types.Float) else None


def _lower_set_lane(context, builder, sig, args):  # noqa: ANN001, ANN202
    x = context.cast(builder, args[2], sig.args[2], types.float64)
    if isinstance(sig.args[0], Lanes):
        return builder.insert_element(args[0], x, args[1])
    return x


_register(set_lane, _type_set_lane, _lower_set_lane)


def _type_lane_count(v=None, *rest):  # noqa: ANN001, ANN202
    if rest or v is None:
        return None
    return signature(types.intp, v)


def _lower_lane_count(context, builder, sig, args):  # noqa: ANN001, ANN202
    t = sig.args[0]
    return context.get_constant(types.intp, t.width if isinstance(t, Lanes | LaneMask) else 1)


_register(lane_count, _type_lane_count, _lower_lane_count)


def _type_unary(x=None, *rest):  # noqa: ANN001, ANN202
    if rest:
        return None
    if isinstance(x, Lanes):
        return signature(x, x)
    return signature(types.float64, x) if _scalar(x) else None


def _lower_sqrt(context, builder, sig, args):  # noqa: ANN001, ANN202
    if isinstance(sig.args[0], Lanes):
        return _vector_intrinsic(builder, "llvm.sqrt", args[0].type, [args[0]])
    x = context.cast(builder, args[0], sig.args[0], types.float64)
    return context.get_function(math.sqrt, signature(types.float64, types.float64))(builder, [x])


_register(vsqrt, _type_unary, _lower_sqrt)


def _lower_per_lane(fn: Callable, arity: int) -> Callable:
    """Lowering that calls numba's scalar ``fn`` (libm) on every lane, or once on a scalar."""
    scalar_sig = signature(types.float64, *([types.float64] * arity))

    def lower(context, builder, sig, args):  # noqa: ANN001, ANN202
        impl = context.get_function(fn, scalar_sig)
        out_t = sig.return_type
        if not isinstance(out_t, Lanes):
            xs = [context.cast(builder, a, t, types.float64) for a, t in zip(args, sig.args, strict=True)]
            return impl(builder, xs)
        vs = [context.cast(builder, a, t, out_t) for a, t in zip(args, sig.args, strict=True)]
        out = ir.Constant(vs[0].type, ir.Undefined)
        for k in range(out_t.width):
            i = ir.Constant(ir.IntType(32), k)
            out = builder.insert_element(out, impl(builder, [builder.extract_element(v, i) for v in vs]), i)
        return out

    return lower


def _type_binary(y=None, x=None, *rest):  # noqa: ANN001, ANN202
    if rest:
        return None
    out = _value_type(y, x)
    return None if out is None else signature(out, y, x)


for _fn, _math in ((vsin, math.sin), (vcos, math.cos), (vexp, math.exp), (vtanh, math.tanh)):
    _register(_fn, _type_unary, _lower_per_lane(_math, 1))
_register(vatan2, _type_binary, _lower_per_lane(math.atan2, 2))


# ---- blocks: several bodies of one scenario in one vector --------------------------------------------------
BLOCK = 4
"""Bodies per block of a scalar kernel's per-body pass (:func:`block_load`): four doubles, one ``ymm``."""


def block_width(a):  # noqa: ANN001, ANN201
    """Bodies per block of an array: :data:`BLOCK` for ``float64`` (one scenario), 1 for lanes (several)."""
    raise NotImplementedError("compiled code only")


def block_load(a, j):  # noqa: ANN001, ANN201
    """``a[j : j + block_width(a)]`` as one value: lanes of consecutive elements (a lane array: ``a[j]``)."""
    raise NotImplementedError("compiled code only")


def block_store(a, j, v):  # noqa: ANN001, ANN201
    """Store :func:`block_load`'s value back at ``a[j]`` onwards."""
    raise NotImplementedError("compiled code only")


def _block_of(a: types.Type) -> types.Type | None:
    if not (isinstance(a, types.Array) and a.ndim == 1):
        return None
    if isinstance(a.dtype, Lanes):
        return a.dtype
    return Lanes(BLOCK) if a.dtype == types.float64 else None


def _type_block_width(a=None, *rest):  # noqa: ANN001, ANN202
    return None if rest or _block_of(a) is None else signature(types.intp, a)


def _lower_block_width(context, builder, sig, args):  # noqa: ANN001, ANN202
    return context.get_constant(types.intp, 1 if isinstance(sig.args[0].dtype, Lanes) else BLOCK)


def _element_pointer(context, builder, aryty, ary, j):  # noqa: ANN001, ANN202
    arr = context.make_array(aryty)(context, builder, ary)
    return cgutils.get_item_pointer(context, builder, aryty, arr, [j], wraparound=False)


def _type_block_load(a=None, j=None, *rest):  # noqa: ANN001, ANN202
    t = _block_of(a)
    return None if rest or t is None or not isinstance(j, types.Integer) else signature(t, a, j)


def _lower_block_load(context, builder, sig, args):  # noqa: ANN001, ANN202
    aryty, out = sig.args[0], sig.return_type
    ptr = _element_pointer(context, builder, aryty, args[0], args[1])
    vt = context.get_value_type(out)
    return builder.load(builder.bitcast(ptr, vt.as_pointer()), align=8)


def _type_block_store(a=None, j=None, v=None, *rest):  # noqa: ANN001, ANN202
    t = _block_of(a)
    if rest or t is None or not isinstance(j, types.Integer) or not (v == t or _scalar(v)):
        return None
    return signature(types.none, a, j, t)


def _lower_block_store(context, builder, sig, args):  # noqa: ANN001, ANN202
    aryty, t = sig.args[0], sig.args[2]
    ptr = _element_pointer(context, builder, aryty, args[0], args[1])
    vt = context.get_value_type(t)
    builder.store(args[2], builder.bitcast(ptr, vt.as_pointer()), align=8)
    return context.get_dummy_value()


_register(block_width, _type_block_width, _lower_block_width)
_register(block_load, _type_block_load, _lower_block_load)
_register(block_store, _type_block_store, _lower_block_store)
