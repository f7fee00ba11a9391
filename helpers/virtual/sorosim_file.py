"""A SoroSim tip-release test, read from its own file: another solver's rod, held deflected and released.

SoroSim (an independent Cosserat-rod solver) computed these; they are simulations, not measurements
(``data/external/sorosim/README.md``). A test's file is tab-separated, 13 columns:

- line 1: SoroSim's damping parameter (its own, not a modal damping ratio), nine zeros, the gravity vector
  (m/s^2, the last three);
- line 2: 0, then the holding wrench at the rod's middle and at its tip, each as moment (N m, three) then
  force (N, three);
- then one row per sample: time (s), the middle's pose and the tip's pose, each as three angles (rad) then the
  position (m), in the file's frame: ``x`` along the unloaded rod, from the clamp.

The rod's description (length, radius, material) is the JSON beside it whose ``test_type`` names the same
rod (``SpringSteelRodMuJoCo_1`` for ``SpringSteelRodMuJoCo_*.txt``). :func:`read_sorosim` returns a
:class:`SoroSimTest`; a file that is not such a test, or a truncated or malformed one, raises one
:class:`~helpers.recordings.format.RecordingError` naming the file and the line (exit status 5).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from helpers.recordings.format import RecordingError

__all__ = ["SoroSimTest", "read_sorosim", "N_COLUMNS", "MIN_ROWS"]

N_COLUMNS = 13
"""Columns of every line of a test's file."""

MIN_ROWS = 10
"""Fewest samples a test may hold."""


@dataclass(frozen=True)
class SoroSimTest:
    """One tip-release test (SI units, the file's frame).

    Attributes
    ----------
    name : str
        The file's stem.
    path : pathlib.Path
    t : numpy.ndarray
        Sample times, s (0: the release).
    mid, tip : numpy.ndarray
        Positions of the rod's middle and tip, m, shape (n, 3).
    mid_angles, tip_angles : numpy.ndarray
        Their orientation angles as the file gives them, rad, shape (n, 3).
    gravity : numpy.ndarray
        Gravity, m/s^2.
    damping_parameter : float
        SoroSim's damping parameter (its own definition, not a modal damping ratio).
    mid_force, tip_force, mid_moment, tip_moment : numpy.ndarray
        The holding wrench at the middle and at the tip, released at ``t = 0`` (N, N m).
    length_m, radius_m, youngs_modulus_pa, density_kg_m3, poisson_ratio : float
        The rod, from its description.
    description : pathlib.Path
        The rod's description (JSON).
    sha256 : str
        Of the test's file.
    """

    name: str
    path: Path
    t: np.ndarray
    mid: np.ndarray
    tip: np.ndarray
    mid_angles: np.ndarray
    tip_angles: np.ndarray
    gravity: np.ndarray
    damping_parameter: float
    mid_force: np.ndarray
    tip_force: np.ndarray
    mid_moment: np.ndarray
    tip_moment: np.ndarray
    length_m: float
    radius_m: float
    youngs_modulus_pa: float
    density_kg_m3: float
    poisson_ratio: float
    description: Path
    sha256: str

    @property
    def shear_modulus_pa(self) -> float:
        """``E / (2 (1 + nu))`` (an isotropic material)."""
        return self.youngs_modulus_pa / (2.0 * (1.0 + self.poisson_ratio))


def _fail(path: Path, line: int | None, problem: str) -> RecordingError:
    return RecordingError(f"{path}: line {line}: {problem}" if line else f"{path}: {problem}")


def _row(path: Path, number: int, line: str | None, what: str) -> np.ndarray:
    if line is None or not line.strip():
        raise _fail(path, number, f"missing ({what}): not a whole SoroSim tip-release test")
    fields = line.strip().split("\t")
    if len(fields) != N_COLUMNS:
        raise _fail(path, number, f"{len(fields)} fields, expected {N_COLUMNS} ({what})")
    try:
        values = np.array([float(f) for f in fields])
    except ValueError:
        raise _fail(path, number, f"{line.strip()[:60]!r} is not {N_COLUMNS} numbers ({what})") from None
    if not np.all(np.isfinite(values)):
        raise _fail(path, number, f"a value is not finite ({what})")
    return values


def _description(path: Path) -> tuple[Path, dict[str, float]]:
    """The rod's description beside ``path``: the JSON whose ``test_type`` names the same rod."""
    rod_name = re.sub(r"_\d+\Z", "", path.stem)
    for candidate in sorted(path.parent.glob("*.json")):
        try:
            doc = json.loads(candidate.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            continue
        if not isinstance(doc, dict) or re.sub(r"_\d+\Z", "", str(doc.get("test_type", ""))) != rod_name:
            continue
        try:
            config = doc["generator_config"]
            material = config["material_properties"]
            values = {
                "length_m": config["total_length"],
                "radius_m": material["outer_radius"],
                "youngs_modulus_pa": material["youngs_modulus"],
                "density_kg_m3": material["density"],
                "poisson_ratio": material["poisson_ratio"],
            }
        except (KeyError, TypeError) as exc:
            raise RecordingError(f"{candidate}: the rod's description lacks {exc}") from None
        out = {}
        for key, value in values.items():
            try:
                out[key] = float(value)
            except (TypeError, ValueError):
                raise RecordingError(f"{candidate}: {key} = {value!r} is not a number") from None
            if not (np.isfinite(out[key]) and out[key] > 0):
                raise RecordingError(f"{candidate}: {key} = {value!r} must be positive")
        return candidate, out
    raise RecordingError(f"{path}: no description of the rod beside it (a JSON with test_type {rod_name}_N)")


def read_sorosim(path: str | os.PathLike) -> SoroSimTest:
    """Read a SoroSim tip-release test and its rod's description.

    Raises
    ------
    RecordingError
        One line naming the file (and the line): missing, not text, a missing or malformed line, too few
        samples, times that do not increase, a rod without its description.
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise _fail(p, None, "no such file") from None
    except OSError as exc:
        raise _fail(p, None, f"cannot be read ({exc.strerror})") from None
    try:
        lines = data.decode("ascii").splitlines()
    except UnicodeDecodeError:
        raise _fail(p, None, "not a SoroSim tip-release test (not plain text)") from None
    head = _row(p, 1, lines[0] if lines else None, "damping parameter and gravity")
    wrench = _row(p, 2, lines[1] if len(lines) > 1 else None, "the holding wrenches")
    while lines and not lines[-1].strip():
        lines.pop()
    rows = np.array([_row(p, k + 3, line, "a sample") for k, line in enumerate(lines[2:])]).reshape(-1, 13)
    if len(rows) < MIN_ROWS:
        raise _fail(p, len(lines) + 1, f"missing: {len(rows)} samples, a test holds at least {MIN_ROWS}")
    t = rows[:, 0]
    steps = np.diff(t)
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0))
        raise _fail(p, k + 4, f"time {t[k + 1]:g} s does not follow {t[k]:g} s")
    description, rod = _description(p)
    return SoroSimTest(
        name=p.stem, path=p, t=t, mid_angles=rows[:, 1:4], mid=rows[:, 4:7], tip_angles=rows[:, 7:10],
        tip=rows[:, 10:13], gravity=head[10:13], damping_parameter=float(head[0]), mid_moment=wrench[1:4],
        mid_force=wrench[4:7], tip_moment=wrench[7:10], tip_force=wrench[10:13], description=description,
        sha256=hashlib.sha256(data).hexdigest(), **rod,
    )  # fmt: skip
