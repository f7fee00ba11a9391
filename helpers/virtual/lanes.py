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

Why not numba's own vectorisation: LLVM's loop vectoriser gives up on a loop that writes several arrays it
cannot prove apart (it would need run-time overlap checks beyond its budget), and numba leaves LLVM's SLP
vectoriser off (``NUMBA_SLP_VECTORIZE=0``, since a miscompilation, numba issue 8705). Explicit vector types
need neither pass and compile the same on every setting of both.
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
from numba.extending import intrinsic, models, overload, register_model, unbox

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
def select(mask, a, b):  # noqa: ANN001, ANN201 - compiled only (overloads below)
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


@intrinsic
def _select(typingctx, mask, a, b):  # noqa: ANN001, ANN202
    t = Lanes(mask.width)

    def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
        x = context.cast(builder, args[1], sig.args[1], t)
        y = context.cast(builder, args[2], sig.args[2], t)
        return builder.select(args[0], x, y)

    return t(mask, a, b), codegen


def _reduction(name: str) -> Callable:
    @intrinsic
    def reduce(typingctx, mask):  # noqa: ANN001, ANN202
        def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
            return _vector_intrinsic(builder, f"llvm.vector.reduce.{name}", ir.IntType(1), [args[0]])

        return types.boolean(mask), codegen

    return reduce


_reduce_or = _reduction("or")
_reduce_and = _reduction("and")


@intrinsic
def _extract(typingctx, v, k):  # noqa: ANN001, ANN202
    out = types.float64 if isinstance(v, Lanes) else types.boolean

    def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
        return builder.extract_element(args[0], args[1])

    return out(v, k), codegen


@intrinsic
def _insert(typingctx, v, k, x):  # noqa: ANN001, ANN202
    def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
        val = context.cast(builder, args[2], sig.args[2], types.float64)
        return builder.insert_element(args[0], val, args[1])

    return v(v, k, x), codegen


@intrinsic
def _vsqrt(typingctx, v):  # noqa: ANN001, ANN202
    def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
        return _vector_intrinsic(builder, "llvm.sqrt", args[0].type, [args[0]])

    return v(v), codegen


@overload(select)
def _ov_select(mask, a, b):  # noqa: ANN001, ANN202
    if isinstance(mask, LaneMask):
        return lambda mask, a, b: _select(mask, a, b)
    if isinstance(mask, types.Boolean):
        return lambda mask, a, b: a if mask else b
    return None


@overload(any_lane)
def _ov_any_lane(mask):  # noqa: ANN001, ANN202
    if isinstance(mask, LaneMask):
        return lambda mask: _reduce_or(mask)
    if isinstance(mask, types.Boolean):
        return lambda mask: mask
    return None


@overload(all_lane)
def _ov_all_lane(mask):  # noqa: ANN001, ANN202
    if isinstance(mask, LaneMask):
        return lambda mask: _reduce_and(mask)
    if isinstance(mask, types.Boolean):
        return lambda mask: mask
    return None


@overload(lnot)
def _ov_lnot(mask):  # noqa: ANN001, ANN202
    if isinstance(mask, LaneMask):
        return lambda mask: ~mask
    if isinstance(mask, types.Boolean):
        return lambda mask: not mask
    return None


@overload(lane)
def _ov_lane(v, k):  # noqa: ANN001, ANN202
    if isinstance(v, Lanes | LaneMask):
        return lambda v, k: _extract(v, k)
    if isinstance(v, types.Float | types.Boolean | types.Integer):
        return lambda v, k: v
    return None


@overload(set_lane)
def _ov_set_lane(v, k, x):  # noqa: ANN001, ANN202
    if isinstance(v, Lanes):
        return lambda v, k, x: _insert(v, k, x)
    if isinstance(v, types.Float):
        return lambda v, k, x: x
    return None


@overload(lane_count)
def _ov_lane_count(v):  # noqa: ANN001, ANN202
    if isinstance(v, Lanes | LaneMask):
        w = v.width
        return lambda v: w
    if isinstance(v, types.Float | types.Boolean | types.Integer):
        return lambda v: 1
    return None


@overload(vsqrt)
def _ov_vsqrt(x):  # noqa: ANN001, ANN202
    if isinstance(x, Lanes):
        return lambda x: _vsqrt(x)
    if isinstance(x, types.Float):
        return lambda x: math.sqrt(x)
    return None


def _per_lane(fn: Callable, name: str) -> Callable:
    """A function that calls the scalar ``fn`` (libm) on every lane: the same bits as on a scalar."""

    def stub(x):  # noqa: ANN001, ANN202
        raise NotImplementedError("compiled code only")

    stub.__name__ = stub.__qualname__ = name
    stub.__doc__ = f"``math.{fn.__name__}`` of every lane (one libm call per lane)."

    @overload(stub)
    def _ov(x):  # noqa: ANN001, ANN202
        if isinstance(x, Lanes):
            w = x.width

            def impl(x):  # noqa: ANN001, ANN202
                out = x
                for k in range(w):
                    out = _insert(out, k, fn(_extract(x, k)))
                return out

            return impl
        if isinstance(x, types.Float):
            return lambda x: fn(x)
        return None

    return stub


vsin = _per_lane(math.sin, "vsin")
vcos = _per_lane(math.cos, "vcos")
vexp = _per_lane(math.exp, "vexp")
vtanh = _per_lane(math.tanh, "vtanh")


def vatan2(y, x):  # noqa: ANN001, ANN201
    """``math.atan2`` of every lane (one libm call per lane)."""
    raise NotImplementedError("compiled code only")


@overload(vatan2)
def _ov_vatan2(y, x):  # noqa: ANN001, ANN202
    if isinstance(y, Lanes) and x == y:
        w = y.width

        def impl(y, x):  # noqa: ANN001, ANN202
            out = y
            for k in range(w):
                out = _insert(out, k, math.atan2(_extract(y, k), _extract(x, k)))
            return out

        return impl
    if isinstance(y, types.Float) and isinstance(x, types.Float):
        return lambda y, x: math.atan2(y, x)
    return None
