"""Every ring-down of a recording: where its configuration signal comes to rest, the mode identified after it.

A structure whose configuration is moved in steps (DROPBEAR's roller, the arm's cable) rings after every
move, at a frequency that depends on where it stopped. :func:`identify_ringdowns` finds every instant the
configuration signal comes to rest (:func:`find_rests`), and identifies the ring-down after every rest of at
least :data:`MIN_REST_S` with the paper's estimators (:mod:`helpers.paper.identify`: log decrement, FFT,
damped-sine fit) and their uncertainty; shorter rests are named, not identified.

**Rests.** The configuration signal is low-passed (zero-phase Butterworth, :data:`SMOOTH_HZ`) and
differentiated; it moves where its speed exceeds :data:`SPEED_THRESHOLD` (the signal's unit per second), and a
rest is a stretch without motion that begins after one (the quiet stretch a file starts with is no stop). Its
position is the signal's median over the rest.

**Ring-downs.** Each vibration channel is band-passed (zero-phase Butterworth, :data:`BAND_HZ`); the window is
the rest's first :data:`WINDOW_S` (or the whole rest, when shorter). The reported mode is the damped-sine fit
on the first channel over the whole window (``f_hz``, ``zeta``, with the fit's standard errors); the FFT peak
and the log decrement on the same window are reported beside it.

**How poorly the damping is determined.** A fit's standard error assumes white residuals; on these ring-downs
it is far smaller than the disagreement of estimates that should agree. So the interval of ``zeta``
(``zeta_lo``-``zeta_hi``) spans every estimate made on that ring-down, each widened by its 95 % interval
(1.96 standard errors): the damped-sine fit and the log decrement, on every vibration channel, over the whole
window and over each of its halves (an amplitude-dependent or non-viscous damping shows as halves that
disagree). ``zeta_other`` is the fit on the second channel. The frequency is determined far better: its
estimates agree to a few tenths of a percent.

``python -m helpers ringdowns FILE [--format dropbear] [--csv PATH|-]`` prints the table as CSV (one row per
ring-down) and names the rests it skipped (``docs/external_data.md``).
"""

from __future__ import annotations

import argparse
import io
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import signal

from helpers.base.cli import DefaultsHelp, arg_number
from helpers.base.jsonfile import atomic_write
from helpers.paper.identify import IdentificationResult, identify
from helpers.recordings.format import Recording, RecordingError
from helpers.research.dropbear import configuration_column, read_dropbear

__all__ = [
    "MIN_REST_S", "WINDOW_S", "BAND_HZ", "SMOOTH_HZ", "SPEED_THRESHOLD", "FORMATS", "COLUMNS", "Rest",
    "Ringdowns", "find_rests", "identify_ringdowns", "to_csv", "add_arguments", "run",
]  # fmt: skip

MIN_REST_S = 0.3
"""Shortest rest whose ring-down is identified, s."""

WINDOW_S = 0.6
"""The longest window analysed after a stop, s."""

BAND_HZ = (10.0, 80.0)
"""Pass band of the vibration channels, Hz (DROPBEAR's first mode lies at 26-42 Hz)."""

BAND_ORDER = 4
"""Order of the band-pass Butterworth (applied forwards and backwards)."""

SMOOTH_HZ = 10.0
"""Cut-off of the low-pass applied to the configuration signal before it is differentiated, Hz."""

SPEED_THRESHOLD = 0.3
"""The configuration signal moves where its smoothed speed exceeds this, its unit per second (DROPBEAR:
V/s; a step of 0.43 V takes about 0.25 s, the sensor's noise after the low-pass is about 0.02 V/s)."""

Z95 = 1.96
"""Standard errors each side of an estimate in its 95 % interval."""

FORMATS = {"dropbear": (read_dropbear, ("low_g_accel_v", "accel_v"))}
"""``--format`` -> (the reader, the vibration channels, the first reported)."""

COLUMNS: dict[str, tuple[str, str]] = {
    "t_stop_s": ("%.4f", "when the configuration signal came to rest, s from the file's start"),
    "position": ("%.4f", "the configuration signal at rest (its median over the rest), in its unit"),
    "start": ("%.4f", "the previous rest's position: where the move that ended here began"),
    "direction": ("%s", "up or down: the rest's position against the previous rest's"),
    "rest_s": ("%.3f", "how long the rest lasted, s"),
    "window_s": ("%.3f", "the window analysed, from the stop, s"),
    "f_hz": ("%.3f", "damped frequency, damped-sine fit on the first channel, Hz"),
    "f_se_hz": ("%.4f", "its standard error (white-residual assumption), Hz"),
    "f_fft_hz": ("%.3f", "the FFT peak on the same window, Hz"),
    "f_logdec_hz": ("%.3f", "the log decrement's frequency (extremum spacing), Hz"),
    "zeta": ("%.5f", "damping ratio, damped-sine fit on the first channel"),
    "zeta_se": ("%.5f", "its standard error (white-residual assumption: optimistic)"),
    "zeta_logdec": ("%.5f", "the log decrement's damping ratio on the same window"),
    "zeta_lo": ("%.5f", "the interval of zeta: the lowest 95 % bound of every estimate on this ring-down"),
    "zeta_hi": ("%.5f", "the interval of zeta: the highest 95 % bound of every estimate on this ring-down"),
    "zeta_other": ("%.5f", "damped-sine fit on the second channel (NaN if it failed)"),
    "n_estimates": ("%d", "estimates of zeta the interval spans"),
    "n_cycles": ("%.1f", "damped periods in the window"),
}
"""The table's columns in order: (CSV format, meaning)."""


@dataclass(frozen=True)
class Rest:
    """A stretch where the configuration signal does not move, after a move.

    Attributes
    ----------
    start, end : int
        Its first sample and the sample after its last.
    t_start_s, duration_s : float
        When it began (the stop) and how long it lasted, s.
    position : float
        The signal's median over the rest.
    previous : float or None
        The previous rest's position (the quiet stretch the file starts with counts), None for the first.
    """

    start: int
    end: int
    t_start_s: float
    duration_s: float
    position: float
    previous: float | None

    @property
    def direction(self) -> str:
        """``up`` or ``down`` against the previous rest (``up`` for the first)."""
        return "down" if self.previous is not None and self.position < self.previous else "up"


def find_rests(
    t: np.ndarray, x: np.ndarray, *, smooth_hz: float = SMOOTH_HZ, speed_threshold: float = SPEED_THRESHOLD
) -> list[Rest]:
    """Every rest of the configuration signal ``x(t)`` that begins after a move.

    Parameters
    ----------
    t, x : numpy.ndarray
        Uniformly sampled time (s) and configuration signal.
    smooth_hz : float
        Low-pass cut-off before differentiating, Hz.
    speed_threshold : float
        The signal moves where its smoothed speed exceeds this (its unit per second).

    Returns
    -------
    list of Rest
        In time order.
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    fs = 1.0 / float(np.median(np.diff(t)))
    if not 0.0 < smooth_hz < 0.5 * fs:
        raise ValueError(f"smooth_hz must lie in (0, {0.5 * fs:g}) Hz, got {smooth_hz!r}")
    sos = signal.butter(2, smooth_hz, fs=fs, output="sos")
    speed = np.abs(np.gradient(signal.sosfiltfilt(sos, x), t))
    still = (speed <= speed_threshold).astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still, [0]])))
    rests, previous = [], None
    for start, end in zip(edges[::2], edges[1::2], strict=True):
        position = float(np.median(x[start:end]))
        if start > 0:
            duration = (end - start) / fs
            rests.append(Rest(int(start), int(end), float(t[start]), duration, position, previous))
        previous = position
    return rests


@dataclass(frozen=True)
class Ringdowns:
    """The ring-downs of one recording.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per identified ring-down, the columns of :data:`COLUMNS`.
    skipped : pandas.DataFrame
        The rests not identified: ``t_stop_s``, ``rest_s``, ``position``, ``reason``.
    recording : str
        The recording's name.
    source : dict
        The recording's ``meta["source"]`` (dataset, file, licence).
    channels : tuple of str
        The vibration channels, the first reported.
    """

    table: pd.DataFrame
    skipped: pd.DataFrame
    recording: str
    source: dict
    channels: tuple[str, ...]

    def notes(self, min_rest_s: float = MIN_REST_S) -> list[str]:
        """What a reader of the table must know: the skipped rests and how poorly the damping is known."""
        lines = []
        short = self.skipped[self.skipped["reason"].str.startswith("shorter")]
        if len(short):
            listed = ", ".join(f"{r.t_stop_s:.3f} s ({r.rest_s:.3f} s at {r.position:.3f})"
                               for r in short.itertuples())  # fmt: skip
            lines.append(f"skipped {len(short)} rest(s) shorter than {min_rest_s:g} s: {listed}")
        for r in self.skipped[~self.skipped.index.isin(short.index)].itertuples():
            lines.append(f"skipped the rest at {r.t_stop_s:.3f} s ({r.position:.3f}): {r.reason}")
        tab = self.table
        if len(tab):
            width = (tab["zeta_hi"] - tab["zeta_lo"]) / tab["zeta"]
            own = np.median(tab["zeta_se"] / tab["zeta"]) * 100
            f_gap = np.max(np.abs(tab["f_fft_hz"] - tab["f_hz"]))
            lines.append(
                f"damping is poorly determined: the interval of zeta (every estimate of the same ring-down: "
                f"fit and log decrement, {len(self.channels)} channels, the window and its halves, each "
                f"+-1.96 standard errors) is {np.median(width):.1f} times zeta wide (median; up to "
                f"{width.max():.0f}), while each fit's own standard error is {own:.1f} % of zeta (median); "
                f"the frequency's estimates (fit, FFT) agree within {f_gap:.2f} Hz"
            )
        licence = self.source.get("licence")
        if licence:
            dataset = self.source.get("dataset", "the data")
            lines.append(f"{dataset} is {licence}: this table, derived from it, is {licence} too")
        return lines


def _bandpassed(recording: Recording, channels: tuple[str, ...], band_hz: tuple[float, float]) -> dict:
    fs = float(recording.meta["rate_hz"])
    lo, hi = band_hz
    if not 0.0 < lo < hi < 0.5 * fs:
        raise ValueError(f"band must satisfy 0 < low < high < {0.5 * fs:g} Hz, got {band_hz!r}")
    sos = signal.butter(BAND_ORDER, [lo, hi], btype="band", fs=fs, output="sos")
    missing = [c for c in channels if c not in recording.frame.columns]
    if missing:
        raise ValueError(f"{recording.name}: no channel(s) {missing}; it has {list(recording.frame.columns)}")
    return {c: signal.sosfiltfilt(sos, recording.frame[c].to_numpy(dtype=float)) for c in channels}


def _identify(t: np.ndarray, y: np.ndarray, window: tuple[float, float]) -> IdentificationResult | None:
    try:
        return identify(t, y, window=window)
    except (ValueError, RuntimeError):
        return None


def _intervals(results: list[IdentificationResult | None]) -> list[tuple[float, float]]:
    """The 95 % intervals of zeta of the fit and the log decrement of every result."""
    out = []
    for res in results:
        for est in () if res is None else (res.fit, res.logdec):
            if est is not None and math.isfinite(est.zeta_std):
                out.append((max(0.0, est.zeta - Z95 * est.zeta_std), est.zeta + Z95 * est.zeta_std))
    return out


def identify_ringdowns(
    recording: Recording,
    channels: tuple[str, ...] = FORMATS["dropbear"][1],
    *,
    min_rest_s: float = MIN_REST_S,
    window_s: float = WINDOW_S,
    band_hz: tuple[float, float] = BAND_HZ,
    smooth_hz: float = SMOOTH_HZ,
    speed_threshold: float = SPEED_THRESHOLD,
) -> Ringdowns:
    """Identify the ring-down after every rest of ``recording``'s configuration signal.

    Parameters
    ----------
    recording : Recording
        With a configuration signal (:func:`helpers.research.dropbear.configuration_column`) and the
        vibration ``channels``.
    channels : tuple of str
        Vibration channels; the first is the one reported, every one enters the interval of zeta.
    min_rest_s, window_s : float
        Shortest rest identified, longest window (s).
    band_hz : (float, float)
        Pass band of the vibration channels, Hz (:data:`BAND_HZ`).
    smooth_hz, speed_threshold : float
        How rests are found (:func:`find_rests`; :data:`SMOOTH_HZ`, :data:`SPEED_THRESHOLD`).

    Returns
    -------
    Ringdowns

    Raises
    ------
    RecordingError
        If no rest lasts ``min_rest_s`` or more, or none could be identified (one line naming the file).
    ValueError
        For arguments out of range or channels the recording lacks.
    """
    if not 0.0 < min_rest_s <= window_s:
        raise ValueError(f"min_rest_s must lie in (0, window_s = {window_s:g}] s, got {min_rest_s!r}")
    channels = tuple(channels)
    t = recording.frame["t_s"].to_numpy(dtype=float)
    config = configuration_column(recording)
    rests = find_rests(t, recording.frame[config].to_numpy(dtype=float), smooth_hz=smooth_hz,
                       speed_threshold=speed_threshold)  # fmt: skip
    filtered = _bandpassed(recording, channels, band_hz)
    rows, skipped = [], []
    for rest in rests:
        where = {"t_stop_s": rest.t_start_s, "rest_s": rest.duration_s, "position": rest.position}
        if rest.duration_s < min_rest_s:
            skipped.append({**where, "reason": f"shorter than {min_rest_s:g} s"})
            continue
        length = min(window_s, rest.duration_s)
        window = (rest.t_start_s, rest.t_start_s + length)
        try:
            res = identify(t, filtered[channels[0]], window=window)
        except (ValueError, RuntimeError) as exc:
            skipped.append({**where, "reason": f"identification failed: {exc}"})
            continue
        assert res.fit is not None
        halves = [(window[0], window[0] + 0.5 * length), (window[0] + 0.5 * length, window[1])]
        results: list[IdentificationResult | None] = [res]
        for i, c in enumerate(channels):
            if i > 0:
                results.append(_identify(t, filtered[c], window))
            results += [_identify(t, filtered[c], half) for half in halves]
        zetas = _intervals(results)
        other = results[3] if len(channels) > 1 else None
        rows.append({
            **where,
            "start": rest.previous,
            "direction": rest.direction,
            "window_s": length,
            "f_hz": res.fit.omega_d / (2.0 * math.pi),
            "f_se_hz": res.fit.omega_d_std / (2.0 * math.pi),
            "f_fft_hz": res.fft.frequency_hz,
            "f_logdec_hz": res.logdec.omega_d / (2.0 * math.pi),
            "zeta": res.fit.zeta,
            "zeta_se": res.fit.zeta_std,
            "zeta_logdec": res.logdec.zeta,
            "zeta_lo": min(z[0] for z in zetas),
            "zeta_hi": max(z[1] for z in zetas),
            "zeta_other": math.nan if other is None else other.zeta,
            "n_estimates": len(zetas),
            "n_cycles": res.n_cycles,
        })  # fmt: skip
    name = str(recording.path) if recording.path is not None else recording.name
    if not rows:
        longest = max(rests, key=lambda r: r.duration_s, default=None)
        what = "no rest" if longest is None else (
            f"the longest rest lasts {longest.duration_s:.3f} s at {longest.t_start_s:.3f} s"
        )
        failed = [s for s in skipped if s["reason"].startswith("identification")]
        if failed:
            raise RecordingError(f"{name}: no ring-down could be identified ({failed[0]['reason']})")
        raise RecordingError(
            f"{name}: no rest of the configuration signal ({config}) lasts {min_rest_s:g} s or more "
            f"({what}): nothing to identify"
        )
    table = pd.DataFrame(rows, columns=list(COLUMNS))
    skipped_frame = pd.DataFrame(skipped, columns=["t_stop_s", "rest_s", "position", "reason"])
    source = dict(recording.meta.get("source", {}))
    return Ringdowns(table, skipped_frame, recording.name, source, channels)


def to_csv(table: pd.DataFrame) -> str:
    """The table as CSV text with :data:`COLUMNS`' fixed precision (the same digits on every machine)."""
    out = io.StringIO()
    out.write(",".join(COLUMNS) + "\n")
    for row in table[list(COLUMNS)].itertuples(index=False):
        cells = []
        for (fmt, _), value in zip(COLUMNS.values(), row, strict=True):
            is_nan = isinstance(value, float) and math.isnan(value)
            cells.append("nan" if is_nan else fmt % value)
        out.write(",".join(cells) + "\n")
    return out.getvalue()


# -- the command ---------------------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``python -m helpers ringdowns``."""
    parser.formatter_class = DefaultsHelp
    parser.description = (
        "Find every rest of a recording's configuration signal and identify the ring-down after every rest "
        f"of at least {MIN_REST_S:g} s (log decrement, FFT, damped-sine fit); print CSV, one row per "
        "ring-down, and name the rests skipped (docs/external_data.md). Exit status 5 for a file that is "
        "not a trial, is truncated or malformed, or has no rest long enough."
    )
    parser.add_argument("file", type=Path, help="the recording's file (a DROPBEAR trial's .txt)")
    parser.add_argument("--format", choices=list(FORMATS), default="dropbear", help="the file's format")
    parser.add_argument(
        "--csv", default="-", metavar="PATH|-", help="the CSV's file (refused if it exists; --replace), or -"
    )
    parser.add_argument("--replace", action="store_true", help="overwrite the --csv file if it exists")
    parser.add_argument("--min-rest", type=arg_number(0.05, 60.0), default=MIN_REST_S,
                        help="shortest rest identified, s")  # fmt: skip
    parser.add_argument("--window", type=arg_number(0.05, 60.0), default=WINDOW_S,
                        help="longest window after a stop, s")  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Run ``python -m helpers ringdowns``."""
    if args.min_rest > args.window:
        raise ValueError(f"--min-rest {args.min_rest:g} s exceeds --window {args.window:g} s")
    target = None if args.csv == "-" else Path(args.csv)
    if target is not None and target.exists() and not args.replace:
        raise RecordingError(f"{target}: exists already; choose another --csv or pass --replace")
    reader, channels = FORMATS[args.format]
    result = identify_ringdowns(reader(args.file), channels, min_rest_s=args.min_rest, window_s=args.window)
    text = to_csv(result.table)
    if target is None:
        sys.stdout.write(text)
    else:
        atomic_write(target, text.encode())
        print(f"{len(result.table)} ring-downs written to {target}")
    for line in result.notes(args.min_rest):
        print(f"note: {line}", file=sys.stderr)
    return 0
