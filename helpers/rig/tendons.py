"""A rig with several tendons: both boards built for its axes and channels, coordinated programmes, homing.

:meth:`TendonRig.connect` opens the DAQ and stepper boards (hardware, pseudo-terminals or ``virtual://``)
as :class:`~helpers.rig.experiment.Rig` does, checks that both were built for the rig file (its hash in
``HELLO``/``PONG``) and that their ``CONFIG`` reports at least the rig file's tendons (axes on the stepper,
channels and axes on the DAQ), each tendon's travel, and each tendon's release below position 0 exactly as the
rig file gives it (``release_mm``; a stepper whose ``CONFIG`` lists no release has none), else one line:
:class:`~helpers.rig.boards.WrongRig` (exit status 4).
:meth:`TendonRig.run` checks a :class:`~helpers.rig.tendon_safety.TendonProgramme` against every tendon's
limits before any byte is sent (:class:`~helpers.rig.safety.SafetyError`, exit status 3), loads it
(``MSEG``/``WAIT``), samples every channel while it runs and returns the samples with each tendon's tension
(the rig file's nominal load-cell chain: ``docs/rig_file.md``) and cable (steps from zero x mm per step).
:meth:`TendonRig.home` brings every tendon back to zero in one coordinated item. On any error the stepper is
stopped and disabled and the DAQ stopped before the error propagates.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from helpers import __version__ as HELPERS_VERSION
from helpers import rigfile
from helpers.board.tendon_lines import TendonStreamParser
from helpers.live.driver import BoardPair
from helpers.recordings import Recording
from helpers.recordings.tendons import TENDON_SCHEMA_VERSION, TIP_COLUMNS, recorded_columns
from helpers.rig.boards import BOOT_TIMEOUT_S, BoardError, BoardTimeout, CommandRefused, WrongRig
from helpers.rig.daq import DaqBoard
from helpers.rig.stepper import StepperBoard
from helpers.rig.tendon_safety import TendonItem, TendonProgramme, check_tendon_programme
from helpers.rigfile import RigFile
from helpers.rigfile.derived import derived
from helpers.rigfile.recorded import rig_section

__all__ = ["TendonDaq", "TendonStepper", "TendonRig", "tendon_frame", "tendon_recording", "with_twin_tip"]


def _ints(reply: str, skip: int) -> list[int]:
    words = reply.split()[skip:]
    if not words or not all(w.lstrip("-").isdigit() for w in words):
        raise BoardError(f"malformed reply {reply!r}")
    return [int(w) for w in words]


class TendonDaq(DaqBoard):
    """The DAQ board of a build with several channels and axes (samples of every channel and axis)."""

    def configure(self) -> tuple[int, int]:
        """``CONFIG`` -> ``(channels, axes)`` (a board without ``CONFIG``, firmware 2.1: one of each)."""
        try:
            reply = self.command("CONFIG")
        except CommandRefused:
            return 1, 1
        channels, axes = _ints(reply, 2)[:2]
        self.parser = TendonStreamParser(channels, axes)
        return channels, axes


class TendonStepper(StepperBoard):
    """The stepper board of a build with several axes: ``done_positions`` is every axis's ``DONE``."""

    def __init__(self, port, timeout: float = 2.0) -> None:
        super().__init__(port, timeout)
        self.done_positions: tuple[int, ...] | None = None
        self.release: tuple[int, ...] = ()
        """Every axis's release below zero as ``CONFIG`` lists it (:meth:`configure`; empty before)."""

    def _message(self, msg: str) -> None:
        if msg.startswith("DONE"):
            try:
                self.done_positions = tuple(_ints(msg, 1))
            except BoardError:
                self.done_positions = ()
            self.done_position = self.done_positions[0] if self.done_positions else 0
        else:
            super()._message(msg)

    def configure(self) -> tuple[int, tuple[int, ...]]:
        """``CONFIG`` -> ``(axes, travel per axis)`` (firmware 2.1: one axis, travel unknown).

        :attr:`release` is every axis's release below zero that ``CONFIG`` lists after the travels (a build
        with ``RIG_AXIS_RELEASE_STEPS``), else 0 each.
        """
        self.release = ()
        try:
            reply = self.command("CONFIG")
        except CommandRefused:
            return 1, ()
        values = _ints(reply, 2)
        axes, rest = values[0], tuple(values[4:])
        if len(rest) not in (axes, 2 * axes):
            raise BoardError(f"malformed reply {reply!r}: {axes} travels (and {axes} releases) expected")
        self.release = rest[axes:] or (0,) * axes
        return axes, rest[:axes]

    def positions(self) -> tuple[int, ...]:
        """``POS``: every axis's position."""
        return tuple(_ints(self.command("POS"), 2))

    def go(self) -> int:  # noqa: D102
        self.done_positions = None
        return super().go()


class TendonRig(BoardPair):
    """Both boards of a rig with several tendons and its rig file.

    Parameters
    ----------
    daq, stepper : TendonDaq, TendonStepper
        Synchronised drivers whose builds were checked (:meth:`connect` does it).
    rig : RigFile
        The rig file (tendons, limits, load cells).
    source : dict, optional
        Provenance (default ``{"kind": "hardware"}``).
    """

    def __init__(self, daq: TendonDaq, stepper: TendonStepper, rig: RigFile,
                 source: dict[str, Any] | None = None) -> None:  # fmt: skip
        self.daq = daq
        self.stepper = stepper
        self.rig = rig
        self.source = dict(source) if source is not None else {"kind": "hardware"}
        self.axes = rig.n_tendons
        self.positions: tuple[int, ...] = (0,) * rig.n_tendons
        """Every tendon's position as the stepper last reported it (``POS``, ``DONE``)."""
        self.cleanup_timeout = 2.0
        self.last_cleanup: list[str] = []

    # --- connecting ------------------------------------------------------------------------------
    @classmethod
    def connect(
        cls,
        ports: str | Sequence[str] = "virtual",
        rig: RigFile | None = None,
        rig_name: str = "default",
        timeout: float = 2.0,
        hello_timeout: float = BOOT_TIMEOUT_S,
    ) -> TendonRig:
        """Open both boards, check their builds against ``rig`` (default the selected rig file).

        ``ports``: ``"virtual"`` (the in-process virtual rig ``rig_name``) or ``"DAQ,STEPPER"``.

        Raises
        ------
        WrongRig
            A board built for another rig file, or reporting fewer axes or channels than its tendons.
        """
        rig = rigfile.selected() if rig is None else rig
        if ports == "virtual":
            daq_url, stepper_url = f"virtual://daq?rig={rig_name}", f"virtual://stepper?rig={rig_name}"
        else:
            pair = ports.split(",") if isinstance(ports, str) else list(ports)
            if len(pair) != 2:
                raise ValueError(f"ports must be 'virtual' or two ports 'DAQ,STEPPER', got {ports!r}")
            daq_url, stepper_url = (p.strip() for p in pair)
        daq = TendonDaq.open(daq_url, timeout=timeout, hello_timeout=hello_timeout, rig=rig)
        try:
            stepper = TendonStepper.open(stepper_url, timeout=timeout, hello_timeout=hello_timeout, rig=rig)
        except BaseException:
            daq.close()
            raise
        try:
            virtual = daq_url.startswith("virtual://")
            source = {"kind": "virtual-rig", "via": "in-process"} if virtual else None
            self = cls(daq, stepper, rig, source)  # type: ignore[arg-type]
            self._check_builds()
            self.positions = self.stepper.positions()[: rig.n_tendons]
            return self
        except BaseException:
            daq.close()
            stepper.close()
            raise

    def _check_builds(self) -> None:
        n, name = self.rig.n_tendons, self.rig.name
        rig_path = self.rig.source or "FILE"
        rebuild = f"rebuild and flash it with make -C firmware RIG={rig_path} upload-%s PORT=..."
        channels, daq_axes = self.daq.configure()
        if channels < n or daq_axes < n:
            raise WrongRig(
                f"the daq board reports {channels} load-cell channel(s) and {daq_axes} step counter(s), but "
                f"rig '{name}' has {n} tendons: " + rebuild % "daq"
            )
        axes, travel = self.stepper.configure()
        if axes < n:
            raise WrongRig(
                f"the stepper board reports {axes} axis/axes, but rig '{name}' has {n} tendons: "
                + rebuild % "stepper"
            )
        d = derived(self.rig)
        want = d.travel_steps
        short = [i for i, t in enumerate(travel[:n]) if t < want[i]]
        if short:
            i = short[0]
            raise WrongRig(
                f"the stepper board's axis {i} travels {travel[i]} steps, but rig '{name}' gives tendon "
                f"{i + 1} {want[i]}: " + rebuild % "stepper"
            )
        release = self.stepper.release or (0,) * axes
        other = [i for i in range(min(n, len(release))) if release[i] != d.release_steps[i]]
        if other:
            i = other[0]
            raise WrongRig(
                f"the stepper board's axis {i} pays out {release[i]} steps below position 0, but rig "
                f"'{name}' gives tendon {i + 1} {d.release_steps[i]} (release_mm): " + rebuild % "stepper"
            )
        self.axes = axes

    # --- running ---------------------------------------------------------------------------------
    def run(self, programme: TendonProgramme, rate_hz: int = 1000, tail_s: float = 0.5,
            rest_ok: bool = False) -> pd.DataFrame:  # fmt: skip
        """Run ``programme`` from the present positions and record every channel.

        Everything is checked first (:func:`~helpers.rig.tendon_safety.check_tendon_programme`: nothing is
        sent if it fails). The DAQ samples from before ``GO`` until ``tail_s`` after ``DONE``.

        Returns
        -------
        pandas.DataFrame
            :func:`tendon_frame`: ``seq``, ``t_us``, ``adc_i``, ``steps_i`` and the derived ``tension_n_i``,
            ``cable_mm_i`` of every tendon ``i`` (0-based as the boards' axes and channels).
        """
        end = check_tendon_programme(programme, self.rig, self.positions, rest_ok=rest_ok)
        if not (isinstance(rate_hz, int) and self.rig.hardware.daq_rate_min_hz <= rate_hz
                <= self.rig.hardware.daq_rate_max_hz):  # fmt: skip
            raise ValueError(f"rate_hz must be an integer within the DAQ's rates, got {rate_hz!r}")
        start = self.positions
        self.daq.rows.clear()
        try:
            self.stepper.abort()
            self.daq.stop()
            self.stepper.send_all(programme.commands(self.axes))
            self.daq.set_rate(rate_hz)
            self.daq.zero()
            self.daq.start()
            self.stepper.enable(True)
            self.stepper.go()
            self._read_until_done(programme.duration_s, tail_s)
            self.daq.stop()
            self.stepper.enable(False)
        except BaseException:
            self.last_cleanup = self._cleanup()
            raise
        done = self.stepper.done_positions or ()
        self.positions = tuple(done[: self.rig.n_tendons])
        if self.positions != end:
            raise BoardError(f"the stepper board ended at {self.positions}, not at the programme's end {end}")
        frame = tendon_frame(self.daq.rows, self.rig, start, getattr(self.daq.parser, "channels", 1))
        return with_twin_tip(frame, getattr(self.daq.port, "twin_tip_um", None))

    def _read_until_done(self, duration_s: float, tail_s: float) -> None:
        wait = self.daq.waiter(duration_s + tail_s + 5.0)
        t_done: int | None = None
        while True:
            if self.daq.pump() == 0:
                wait.idle(self.daq.port.timeout or 0.0)
            self.daq.check_reset()
            self.stepper.poll()
            self.stepper.check_reset()
            rows = self.daq.rows
            if self.stepper.done_positions is not None and rows:
                t_done = rows[-1][1] if t_done is None else t_done
                if rows[-1][1] - t_done >= tail_s * 1e6:
                    return
            if wait.expired:
                raise BoardTimeout(
                    f"the stepper board did not report DONE within {wait.timeout:.1f} s of a "
                    f"{duration_s:.2f} s programme (it stopped answering)"
                )

    def _cleanup(self) -> list[str]:
        problems = []
        for what, board, fn in (
            ("ABORT", self.stepper, lambda: self.stepper.abort(timeout=self.cleanup_timeout)),
            ("EN 0", self.stepper, lambda: self.stepper.enable(False, timeout=self.cleanup_timeout)),
            ("STOP", self.daq, lambda: self.daq.stop(timeout=self.cleanup_timeout)),
        ):
            board.hello = 0  # a rebooted board still takes the command
            try:
                fn()
            except Exception as exc:  # noqa: BLE001 - cleanup must go on
                problems.append(f"{what} failed: {type(exc).__name__}: {exc}")
        return problems

    def recording(self, frame: pd.DataFrame, programme: TendonProgramme, rate_hz: int = 1000) -> Recording:
        """The last run as a recording of ``schema_version`` 3 (:func:`tendon_recording`)."""
        stats = self.daq.stats
        counts = {"samples": len(frame), "dropped": stats.dropped, "corrupted": stats.corrupted,
                  "overruns": stats.overruns}  # fmt: skip
        scenario = {"kind": "programme", "items": [it.command(self.rig.n_tendons) for it in programme.items]}
        firmware = {"daq": self.daq.version, "stepper": self.stepper.version}
        return tendon_recording(frame, self.rig, rate_hz, counts, self.source, scenario, firmware=firmware)

    def home(self, rate_hz: int = 1000) -> pd.DataFrame | None:
        """Bring every tendon back to zero in one item at half the top speed (None if all are there)."""
        self.positions = self.stepper.positions()[: self.rig.n_tendons]
        if not any(self.positions):
            return None
        floor = derived(self.rig).min_interval_us
        window = 2 * floor * max(abs(p) for p in self.positions)
        back = TendonProgramme((TendonItem(window, tuple(-p for p in self.positions)),))
        return self.run(back, rate_hz=rate_hz, tail_s=0.2, rest_ok=True)


def with_twin_tip(frame: pd.DataFrame, tip_um: Any) -> pd.DataFrame:
    """``frame`` with the twin's tip columns (``tip_x_um`` ..) where the port's world provides them.

    ``tip_um`` is the in-process virtual rig's port method (``twin_tip_um(t_us)``); hardware and
    pseudo-terminal ports have none, and the frame is returned unchanged.
    """
    tips = tip_um(frame["t_us"].to_numpy()) if callable(tip_um) and len(frame) else None
    if tips is None:
        return frame
    out = frame.copy()
    for k, col in enumerate(TIP_COLUMNS):
        out[col] = np.asarray(tips)[:, k]
    return out


def tendon_frame(
    rows: Sequence[Sequence[int]], rig: RigFile, start: Sequence[int], channels: int | None = None
) -> pd.DataFrame:
    """Samples as a frame: ``seq``, ``t_us``, then per tendon ``i`` ``adc_i``, ``steps_i`` and derived values.

    ``steps_i`` counts from zero (the start position plus the DAQ's count since ``ZERO``), ``tension_n_i`` is
    the rig file's nominal chain, ``(adc - offset_counts) / gain_counts_per_n``, and ``cable_mm_i`` is
    ``steps_i`` x mm per step.

    ``rows`` are the DAQ's samples ``(seq, t_us, adc_0.., steps_0..)`` of a board with ``channels`` load
    cells (default the rig's tendons).
    """
    n = rig.n_tendons
    d = derived(rig)
    channels = n if channels is None else channels
    a = np.asarray(rows, dtype=np.int64).reshape(-1, len(rows[0]) if len(rows) else 2 + 2 * n)
    cols: dict[str, Any] = {"seq": a[:, 0], "t_us": a[:, 1]}
    for i in range(n):
        cols[f"adc_{i}"] = a[:, 2 + i]
    for i in range(n):
        cols[f"steps_{i}"] = a[:, 2 + channels + i] + int(start[i])
    for i in range(n):
        cols[f"tension_n_{i}"] = (cols[f"adc_{i}"] - d.offset_counts) / d.gain_counts_per_n[i]
    for i in range(n):
        cols[f"cable_mm_{i}"] = cols[f"steps_{i}"] * d.mm_per_step[i]
    return pd.DataFrame(cols)


def tendon_recording(
    frame: pd.DataFrame, rig: RigFile, rate_hz: int, counts: dict[str, int], source: dict[str, Any],
    scenario: dict[str, Any], status: str = "complete", firmware: dict[str, str] | None = None,
) -> Recording:  # fmt: skip
    """A recording of several tendons (``docs/recording_format.md``, version 3) of a :func:`tendon_frame`.

    The calibration is the rig file's nominal chain per tendon (``calibration.origin`` says so). Provenance
    as version 2's: the rig file, the source, the host's ``helpers`` version and (given) the boards' firmware.
    """
    d = derived(rig)
    n = rig.n_tendons
    meta = {
        "schema_version": TENDON_SCHEMA_VERSION,
        "tendons": n,
        "rig": rig_section(rig),
        "source": dict(source),
        "scenario": dict(scenario),
        "calibration": {
            "newtons_per_count": [1.0 / g for g in d.gain_counts_per_n],
            "offset_counts": [d.offset_counts] * n,
            "mm_per_step": list(d.mm_per_step),
            "origin": f"nominal: rig file {rig.name} ({rig.hash}), [hardware] loop and load_cell_range_n",
        },
        "rate_hz": int(rate_hz),
        "status": status,
        "counts": dict(counts),
        "host": {"helpers": HELPERS_VERSION},
    }
    if firmware is not None:
        meta["firmware"] = dict(firmware)
    if all(c in frame.columns for c in TIP_COLUMNS):
        meta["tip"] = {"origin": "twin-provided: the spatial twin's tip node, clamp frame, at channel 0's "
                       "instant of each sample (not measured)", "unit": "um"}  # fmt: skip
    raw = frame.loc[:, list(recorded_columns(meta))].astype(np.int64).reset_index(drop=True)
    return Recording(frame=raw, meta=meta).derive()
