"""Where a sweep's results live: one file per finished chunk while it runs, one NetCDF file when it is done.

While a sweep runs, ``<output>.parts/`` holds ``sweep.json`` (the resolved definition and the physics
fingerprint it was started with) and one ``chunk-NNNNN.npz`` per finished chunk, each written atomically
(readers and a resumed sweep see a whole chunk or none). A sweep that stops for any reason leaves its
finished chunks there; run it again with the same definition and it computes only the others. A parts folder
of another definition, or of a virtual rig whose code or parameters changed since, is refused.

When every chunk is done, :func:`assemble` builds the :class:`xarray.Dataset` (labelled dimensions: the
grid's parameters, ``sample``, ``shaper``, ``seed`` when on the grid, ``move``; the sampled parameters as
coordinates along ``sample``; the others as scalar coordinates) and :func:`write_dataset` saves it as
NetCDF-3 through scipy (one self-contained file, no further dependency), atomically. Its attributes carry
the resolved definition, the rig's parameters, the code version and the physics fingerprint.
:func:`helpers.research.sweep.files.load_sweep` reads it back.
"""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import io
import json
import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

import helpers
from helpers.base.jsonfile import DataFileError, atomic_write, read_json, remove_stale_temporaries, write_json
from helpers.base.paths import REPO_ROOT
from helpers.base.signals import signals_held
from helpers.research.sweep.definition import PARAMETERS, SweepDefinition
from helpers.research.sweep.shaping import BUILTIN
from helpers.research.sweep.variables import MOVES, STATUS, VARIABLES
from helpers.virtual import RigParameters

__all__ = ["Parts", "assemble", "code_version", "physics_fingerprint", "same_physics", "write_dataset"]

PHYSICS_FILES: tuple[Path, ...] = tuple(
    REPO_ROOT / "helpers" / rel
    for rel in (
        "virtual/_kernel.py",
        "virtual/_driver.py",
        "virtual/parameters.py",
        "virtual/plant.py",
        "virtual/sensor.py",
        "virtual/simulate.py",
        "virtual/statics.py",
        "paper/backbone.py",
    )
)
"""The code of what a run computes: the virtual rig's physics and the backbone it shares with the linear
model (not its exports, the batch runner, the ``solve_ivp`` oracle, the emulated boards or the plots)."""

LEGACY_FINGERPRINTS: dict[str, str] = {
    "c7ea1e195e31eb10": "34ade0a9fd216a8f",
    "82ebe100f05565cc": "34ade0a9fd216a8f",
    "9c6e7182e7a5c303": "34ade0a9fd216a8f",
    "04b23f845147a1c0": "70d3f96c525c571c",
    "1511e4c01b0a1df1": "70d3f96c525c571c",
    "b992664fcc1c845a": "70d3f96c525c571c",
}
"""Fingerprints of the same physics in an earlier form -> today's. The first form was a hash of the files'
bytes (a moved import or a reworded docstring changed it); ``82ebe100f05565cc`` is the present form of the
same sources before the sensor chain's constants became :class:`RigParameters` fields (the rig file as a
value: the same numbers, the gain, offset and every ADC count checked equal) and the kernels gained
a second integrator (RK4, then the default, bit for bit as before: ``tests/test_virtual_world.py`` pins the
bytes). ``9c6e7182e7a5c303`` is the same physics before the planar kernel was written once for one run or
several in SIMD lanes and the statics' modal state shared with the spatial twin: the stored
atlases' runs recomputed by ``run_chunk`` (lanes) gave the same bits (first, middle and last chunk of each of
the three atlases, ``residual_pct`` and ``max_rotor_lag_steps``). The stored atlas (``data/sweeps/``) is
made with the implicit step, the default since: a physics of its own. ``04b23f845147a1c0`` is its
physics before the integrator's docstring in ``virtual/parameters.py`` was reworded (the same code), and
``1511e4c01b0a1df1`` before :class:`~helpers.virtual.plant.ArmLanes` could save, restore and set aside a lane
and take one row of sample times per rig (``tune --lanes``): the kernels unchanged, both integrators' bytes
pinned by ``tests/test_virtual_world.py`` and every lane bitwise its run alone (``tests/test_lanes.py``).
``b992664fcc1c845a`` is the same physics before the kernels' lane driver moved its shared pieces into
``virtual/_driver.py`` (listed above since) and each kernel's ``advance`` began passing plain arrays down (one
compiled form per kind of array): the first, middle and last chunk of each of the three stored atlases,
recomputed by ``run_chunk``, gave the stored ``residual_pct`` and ``max_rotor_lag_steps`` bit for bit."""


def _canonical(source: str) -> str:
    """The code of a module without its docstrings, imports reduced to the names they bind.

    Every dotted name of the package is reduced to ``helpers`` too. What a run computes depends on the code
    and on the objects the imports bind, not on the module paths they come from, nor on the documentation:
    the package's layout may change without changing the fingerprint.
    """
    tree = ast.parse(source)
    bound: set[str] = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if not isinstance(body, list):
            continue
        kept = []
        for i, child in enumerate(body):
            if isinstance(child, ast.Import | ast.ImportFrom):
                bound.update(a.asname or a.name.split(".")[0] for a in child.names)
            elif not (i == 0 and isinstance(child, ast.Expr) and isinstance(child.value, ast.Constant)
                      and isinstance(child.value.value, str)):  # fmt: skip
                kept.append(child)
        node.body = kept or [ast.Pass()]
    text = ast.dump(tree, annotate_fields=False) + "|" + ",".join(sorted(bound))
    return re.sub(r"helpers(\.\w+)+", "helpers", text)


def sources_fingerprint(sources: dict[str, str], rig: dict[str, Any]) -> str:
    """The fingerprint of physics sources (file name -> text) and a rig's parameters (16 hex digits)."""
    h = hashlib.sha256()
    for name in sorted(sources):
        h.update(name.encode())
        h.update(_canonical(sources[name]).encode())
    h.update(json.dumps(rig, sort_keys=True).encode())
    return h.hexdigest()[:16]


def code_version() -> str:
    """``helpers <version>, git <commit>`` (``+ uncommitted changes`` when the tree differs), or no git."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=REPO_ROOT, capture_output=True,
                              text=True, timeout=30)  # fmt: skip
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO_ROOT,
                               capture_output=True, text=True, timeout=30)  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return f"helpers {helpers.__version__}, git unavailable"
    if head.returncode != 0:
        return f"helpers {helpers.__version__}, not a git checkout"
    mark = " + uncommitted changes" if dirty.stdout.strip() else ""
    return f"helpers {helpers.__version__}, git {head.stdout.strip()}{mark}"


def rig_dict(params: RigParameters | None = None) -> dict[str, Any]:
    """The rig's parameters as JSON-safe data."""
    return json.loads(json.dumps(dataclasses.asdict(RigParameters() if params is None else params)))


def physics_fingerprint() -> str:
    """A hash of the virtual rig's code (:data:`PHYSICS_FILES`) and the tuned rig's parameters (16 hex).

    Two sweeps with the same fingerprint ran the same physics; a parts folder with another is not resumed.
    """
    return sources_fingerprint({p.name: p.read_text() for p in PHYSICS_FILES}, rig_dict())


def same_physics(fingerprint: str) -> bool:
    """Whether a dataset's ``physics_fingerprint`` (either form: :data:`LEGACY_FINGERPRINTS`) is today's."""
    return LEGACY_FINGERPRINTS.get(fingerprint, fingerprint) == physics_fingerprint()


class Parts:
    """The folder of finished chunks of one sweep (module docstring).

    Parameters
    ----------
    output : path-like
        The sweep's output file; the folder is ``<output>.parts``.
    definition : SweepDefinition
        The resolved definition.
    """

    def __init__(self, output: str | os.PathLike, definition: SweepDefinition) -> None:
        self.output = Path(output)
        self.folder = self.output.with_name(self.output.name + ".parts")
        self.definition = definition
        self.header = {"definition": definition.to_dict(), "physics": physics_fingerprint()}
        self.digest = hashlib.sha256(json.dumps(self.header, sort_keys=True).encode()).hexdigest()
        """What every chunk file of this sweep carries: a chunk of another sweep is not this one's."""
        self.rejected: list[str] = []
        """Chunk files found damaged or not this sweep's (computed again), with the reason."""

    def open(self) -> list[int]:
        """Create the folder or check it is this sweep's; return the chunks already done."""
        meta = self.folder / "sweep.json"
        if meta.exists():
            old = read_json(meta, "sweep parts header")
            if old.get("definition") != self.header["definition"]:
                raise DataFileError(
                    f"{self.folder} holds an interrupted sweep with another definition: delete it or choose "
                    "another output"
                )
            if old.get("physics") != self.header["physics"]:
                raise DataFileError(
                    f"{self.folder} was started with another virtual rig (code or parameters changed): "
                    "delete it to start again"
                )
        else:
            write_json(meta, self.header)
        return self.done()

    def path(self, chunk: int) -> Path:
        """The file of ``chunk``."""
        return self.folder / f"chunk-{chunk:05d}.npz"

    def done(self) -> list[int]:
        """Chunks whose file is there and sound (checked against the definition); others are computed again.

        A damaged file, or one that is not this sweep's chunk (another sweep's, another chunk's, edited), is
        listed in :attr:`rejected` and left to be overwritten when its chunk is computed again.
        """
        out = []
        remove_stale_temporaries(self.folder)
        for p in sorted(self.folder.glob("chunk-*.npz")):
            try:
                c = int(p.stem.split("-")[1])
            except (IndexError, ValueError):
                continue
            if not 0 <= c < self.definition.n_chunks:
                continue
            try:
                self.load(c)
            except DataFileError as exc:
                self.rejected.append(str(exc))
                continue
            out.append(c)
        return out

    def save(self, result: dict[str, Any]) -> Path:
        """Write a chunk's arrays atomically (signals held, so an interrupt cannot cut it)."""
        arrays = {k: np.asarray(result[k]) for k in ("runs", *VARIABLES)}
        arrays["messages"] = np.array(json.dumps({str(k): v for k, v in result["messages"].items()}))
        arrays["chunk"] = np.array(int(result["chunk"]))
        arrays["sweep_digest"] = np.array(self.digest)
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        with signals_held():
            return atomic_write(self.path(int(result["chunk"])), buf.getvalue())

    def load(self, chunk: int) -> dict[str, Any]:
        """A saved chunk's arrays, checked: this sweep's, this chunk's runs, every variable for each run.

        Raises
        ------
        helpers.base.jsonfile.DataFileError
            Naming the chunk file and what is wrong with it.
        """
        path = self.path(chunk)
        try:
            with np.load(path, allow_pickle=False) as z:
                out = {k: z[k] for k in z.files}
            out["messages"] = json.loads(str(out["messages"]))
        except Exception as exc:  # noqa: BLE001 - whatever the damage, one line naming the file
            why = f"{type(exc).__name__}: {str(exc)[:80]}"
            raise DataFileError(f"{path}: damaged chunk ({why}); it is computed again") from None
        problem = self._problem(chunk, out)
        if problem:
            raise DataFileError(f"{path}: {problem}; it is computed again")
        return out

    def _problem(self, chunk: int, arrays: dict[str, Any]) -> str | None:
        """Why ``arrays`` are not ``chunk`` of this sweep, or None."""
        if str(arrays.get("sweep_digest", "")) != self.digest:
            return "not a chunk of this sweep (another definition or physics, or written by an older version)"
        if int(arrays.get("chunk", -1)) != chunk:
            return f"holds chunk {int(arrays.get('chunk', -1))}, not {chunk}"
        runs = np.asarray(arrays.get("runs", []))
        span = self.definition.chunk_range(chunk)
        expected = np.arange(span.start, span.stop)
        if runs.shape != expected.shape or np.any(runs != expected):
            return "its runs are not the chunk's"
        for name in VARIABLES:
            if name not in arrays or np.asarray(arrays[name]).shape[:1] != runs.shape:
                return f"variable {name} missing or of the wrong shape"
        if not isinstance(arrays["messages"], dict):
            return "messages is not an object"
        return None

    def remove(self) -> None:
        """Delete the folder (after the dataset is written)."""
        shutil.rmtree(self.folder, ignore_errors=True)


def assemble(definition: SweepDefinition, chunks: list[dict[str, Any]]) -> xr.Dataset:
    """The sweep's dataset from its chunks' arrays (every chunk once, any order).

    Parameters
    ----------
    definition : SweepDefinition
        The resolved definition.
    chunks : list of dict
        What :func:`helpers.research.sweep.runs.run_chunk` returned (or :meth:`Parts.load` read).

    Returns
    -------
    xarray.Dataset
    """
    n = definition.n_runs
    flat: dict[str, np.ndarray] = {}
    messages: dict[str, str] = {}
    seen = np.zeros(n, dtype=bool)
    for c in chunks:
        runs = np.asarray(c["runs"], dtype=np.int64)
        if np.any(seen[runs]):
            raise ValueError("assemble: a run appears in two chunks")
        seen[runs] = True
        for name in VARIABLES:
            arr = np.asarray(c[name])
            if name not in flat:
                dtype = np.int8 if name == "status" else float
                flat[name] = np.full((n, *arr.shape[1:]), np.nan if dtype is float else -1, dtype=dtype)
            flat[name][runs] = arr
        messages.update({str(k): v for k, v in c["messages"].items()})
    if not seen.all():
        raise ValueError(f"assemble: {int((~seen).sum())} runs have no result")
    run_dims = list(definition.run_dims)
    shape = definition.run_shape
    seed_on_grid = "seed" in definition.grid
    data_vars = {}
    for name, (extra, unit, meaning) in VARIABLES.items():
        arr = flat[name].reshape(*shape, *flat[name].shape[1:])
        dims = list(run_dims)
        if "seed" in extra:
            if seed_on_grid:
                dims.append("seed")
            else:
                arr = arr[..., 0, :] if "move" in extra else arr[..., 0]
        if "move" in extra:
            dims.append("move")
        if name in ("rig_omega_d_rad_s", "rig_zeta"):  # a property of the rig, not of the shaper
            arr = np.take(arr, 0, axis=run_dims.index("shaper"))
            dims.remove("shaper")
        data_vars[name] = xr.Variable(dims, arr, attrs={"units": unit, "long_name": meaning})
    coords: dict[str, Any] = {"shaper": ("shaper", np.array(definition.shapers, dtype=str)),
                              "move": ("move", np.array(MOVES, dtype=str))}  # fmt: skip
    for dim, values in definition.grid.items():
        dtype = np.int32 if PARAMETERS[dim].integer else float
        coords[dim] = (
            dim,
            np.asarray(values, dtype=dtype),
            {"units": PARAMETERS[dim].unit, "long_name": PARAMETERS[dim].meaning},
        )
    if definition.sample is not None:
        coords["sample"] = ("sample", np.arange(definition.sample["n"], dtype=np.int32))
        for name, values in definition.sample_values().items():
            coords[name] = (
                "sample",
                values,
                {"units": PARAMETERS[name].unit, "long_name": PARAMETERS[name].meaning},
            )
    sampled = set(definition.sample["distributions"]) if definition.sample else set()
    for name, param in PARAMETERS.items():
        if name not in definition.grid and name not in sampled:
            value = definition.fixed.get(name, param.default)
            coords[name] = (
                (),
                np.int32(value) if param.integer else float(value),
                {"units": param.unit, "long_name": param.meaning},
            )
    ds = xr.Dataset(data_vars, coords=coords)
    ds.attrs = {
        "title": f"sweep {definition.name} on the virtual rig (simulated, never measured)",
        "source": "virtual-rig",
        "definition": definition.to_json(),
        "rig_parameters": json.dumps(rig_dict(), sort_keys=True),
        "physics_fingerprint": physics_fingerprint(),
        "code_version": code_version(),
        "status_meaning": json.dumps(STATUS),
        "shapers_meaning": json.dumps(
            {s: BUILTIN.get(s, "custom (see definition)") for s in definition.shapers}
        ),
        "refused_runs": json.dumps(messages, sort_keys=True),
    }
    return ds


def write_dataset(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """Save ``ds`` as NetCDF-3 (scipy), atomically."""
    path = Path(path)
    if path.suffix != ".nc":
        raise ValueError(f"sweep output must be a NetCDF file ending in .nc, got {path.name}")
    data = ds.to_netcdf(None, engine="scipy", format="NETCDF3_64BIT")
    with signals_held():
        return atomic_write(path, bytes(data))
