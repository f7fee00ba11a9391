"""Running a sweep: its chunks as Dask tasks (a local cluster, any scheduler) or in a plain loop.

:func:`run_sweep` resolves the definition, opens the parts folder
(:class:`helpers.research.sweep.store.Parts`:
finished chunks are skipped), sends every remaining chunk to the workers as one task
(:func:`helpers.research.sweep.runs.run_chunk`), writes each result to disk as it arrives (in this process, so
workers need no shared file system), shows a progress bar, and when all chunks are there writes the dataset
and removes the parts. Where the chunks run:

- ``client``: an existing :class:`distributed.Client` (any cluster: ``dask_jobqueue.SLURMCluster``, ...);
- ``scheduler``: the address of a running Dask scheduler (``tcp://host:8786``);
- otherwise a local cluster of ``workers`` processes (default: the machine's cores), one thread each;
- ``serial=True``: no Dask at all, a loop in this process (the same numbers, bit for bit).

Ctrl-C, SIGTERM and SIGHUP stop it: the finished chunks stay on disk, the message says how to resume.
"""

from __future__ import annotations

import logging
import os
import socket
import struct
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import xarray as xr
from tqdm import tqdm

from helpers.base.jsonfile import DataFileError
from helpers.base.locks import folder_lock
from helpers.base.signals import Interrupted
from helpers.research.sweep.definition import SweepDefinition
from helpers.research.sweep.runs import run_chunk
from helpers.research.sweep.shaping import check_shapers
from helpers.research.sweep.store import Parts, assemble, write_dataset

__all__ = ["SweepInterrupted", "SweepReport", "local_client", "run_sweep"]


class SweepInterrupted(Interrupted):
    """A sweep was interrupted; its message says how many chunks are saved and how to resume."""

    def __init__(self, signum: int, message: str) -> None:
        super().__init__(signum)
        self.message = message

    def __str__(self) -> str:
        return self.message


@dataclass
class SweepReport:
    """What a call of :func:`run_sweep` did.

    Attributes
    ----------
    output : pathlib.Path
        The dataset file.
    chunks, resumed, computed : int
        Chunks in the sweep, found on disk, computed now.
    runs : int
        Runs in the sweep.
    wall_s : float
        Wall time of the computation.
    refused : int
        Runs whose design or programme was refused, or whose integration failed (``status`` > 0).
    where : str
        Where the chunks ran.
    stats : dict
        Summed :class:`helpers.virtual.batch.BatchStats` of the chunks computed now.
    """

    output: Path
    chunks: int
    resumed: int
    computed: int
    runs: int
    wall_s: float
    refused: int
    where: str
    stats: dict[str, float] = field(default_factory=dict)
    rejected: list[str] = field(default_factory=list)
    """Chunk files found damaged or not this sweep's, and computed again (one line each)."""


@contextmanager
def local_client(workers: int | None = None, threads: int = 1, processes: bool = True) -> Iterator[Any]:
    """A local Dask cluster of ``workers`` workers (default: the cores) and its client, closed after.

    Parameters
    ----------
    workers : int, optional
        Workers.
    threads : int
        Threads per worker.
    processes : bool
        Each worker in its own process (the default; False: threads of this process, which start at once and
        suit short tests, the kernels releasing the GIL).
    """
    from distributed import Client, LocalCluster  # noqa: PLC0415 - Dask loads only where a sweep runs

    n = workers or os.cpu_count() or 1
    cluster = LocalCluster(n_workers=n, threads_per_worker=threads, processes=processes,
                           dashboard_address=":0", silence_logs=logging.ERROR)  # fmt: skip
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


CONNECT_TIMEOUT_S = 20
"""How long to try reaching a given scheduler before giving up (s)."""

GREETING_TIMEOUT_S = 10.0
"""How long a scheduler may take to send its greeting once connected (s)."""

GREETING_MAX_BYTES = 1 << 20
"""The largest greeting accepted from a scheduler (a Dask scheduler's is under 100 bytes)."""


def probe_scheduler(
    address: str, timeout: float = GREETING_TIMEOUT_S, max_bytes: int = GREETING_MAX_BYTES
) -> None:
    """Check that ``address`` (``tcp://host:port`` or ``host:port``) is a Dask scheduler, before Dask does.

    A Dask scheduler greets every connection at once with a short handshake (a length, then msgpack
    frames: compression, Python version, pickle protocol). Anything else (an HTTP server waits for a request;
    another service sends bytes that read as an absurd length) is refused in one line, within ``timeout`` and
    reading at most ``max_bytes``, instead of hanging or allocating what the bytes ask for.

    Raises
    ------
    ValueError
        Naming the address and what was wrong.
    """
    from distributed.protocol.core import loads  # noqa: PLC0415 - Dask loads only where a sweep runs
    from distributed.protocol.utils import unpack_frames  # noqa: PLC0415

    text = address.removeprefix("tcp://")
    if "://" in text:
        return  # another transport (tls://, ucx://): left to Dask and its timeout
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit():
        raise ValueError(f"scheduler address {address!r}: expected tcp://HOST:PORT")
    where = f"the Dask scheduler at {address}"

    def read(sock: socket.socket, n: int) -> bytes:
        data = b""
        while len(data) < n:
            chunk = sock.recv(n - len(data))
            if not chunk:
                raise ValueError(f"{where} closed the connection without greeting as a Dask scheduler does")
            data += chunk
        return data

    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout) as sock:
            sock.settimeout(timeout)
            (n,) = struct.unpack("<Q", read(sock, 8))
            if not 0 < n <= max_bytes:
                raise ValueError(
                    f"{where} is not a Dask scheduler: its first message announces {n} bytes (a scheduler's "
                    f"greeting is under {max_bytes} bytes)"
                )
            frames, buffers = unpack_frames(read(sock, n), partial=True)
            if sum(buffers) > max_bytes:
                raise ValueError(f"{where} is not a Dask scheduler: its greeting has {sum(buffers)} bytes")
            greeting = loads(frames, deserialize=False)
    except TimeoutError:
        raise ValueError(
            f"{where} did not greet as a Dask scheduler within {timeout:g} s (is it a scheduler's address?)"
        ) from None
    except OSError as exc:
        raise ValueError(f"cannot reach {where}: {exc}") from None
    except ValueError:
        raise
    except Exception as exc:  # noqa: BLE001 - whatever the bytes were, they were not a scheduler's greeting
        why = type(exc).__name__
        raise ValueError(f"{where} is not a Dask scheduler: its greeting does not decode ({why})") from None
    if not (isinstance(greeting, dict) and "pickle-protocol" in greeting):
        raise ValueError(f"{where} is not a Dask scheduler: it greeted with {str(greeting)[:60]!r}")


@contextmanager
def _client_for(client: Any, scheduler: str | None, workers: int | None) -> Iterator[tuple[Any, str]]:
    if client is not None:
        yield client, f"the given Dask client ({client.scheduler.address})"
        return
    if scheduler is not None:
        from distributed import Client  # noqa: PLC0415 - Dask loads only where a sweep runs

        probe_scheduler(scheduler, timeout=GREETING_TIMEOUT_S)
        try:
            c = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except OSError as exc:
            raise ValueError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        try:
            yield c, f"the Dask scheduler at {scheduler}"
        finally:
            c.close()
        return
    with local_client(workers) as c:
        yield c, f"a local Dask cluster of {len(c.scheduler_info()['workers'])} worker(s)"


def _start(bar: Any) -> None:
    """Show a bar made with an infinite ``delay`` now."""
    bar.delay = 0
    bar.refresh()


def run_sweep(
    definition: SweepDefinition,
    output: str | os.PathLike,
    *,
    client: Any = None,
    scheduler: str | None = None,
    workers: int | None = None,
    threads: int = 1,
    serial: bool = False,
    progress: bool = True,
    overwrite: bool = False,
    keep_parts: bool = False,
) -> tuple[xr.Dataset, SweepReport]:
    """Run a sweep (or finish an interrupted one) and write its dataset to ``output`` (``.nc``).

    Parameters
    ----------
    definition : SweepDefinition
        The sweep (resolved here if it is not yet).
    output : path-like
        The NetCDF file to write.
    client, scheduler, workers, serial
        Where the chunks run (module docstring).
    threads : int
        Threads of the batch inside each task (for workers with several cores and one task at a time).
    progress : bool
        Show a progress bar on stderr.
    overwrite : bool
        Replace an existing output file (otherwise refused).
    keep_parts : bool
        Keep the parts folder after writing the dataset.

    Returns
    -------
    (xarray.Dataset, SweepReport)

    Raises
    ------
    helpers.base.jsonfile.DataFileError
        The output exists (without ``overwrite``), or a parts folder belongs to another sweep.
    ValueError
        A bad definition, output name or scheduler address.
    SweepInterrupted
        On Ctrl-C, SIGTERM or SIGHUP: the finished chunks are on disk.
    """
    output = Path(output)
    if output.suffix != ".nc":
        raise ValueError(f"sweep output must be a NetCDF file ending in .nc, got {output.name}")
    if output.exists() and not overwrite:
        raise DataFileError(f"{output} exists already: pass --overwrite (overwrite=True) to replace it")
    # one sweep at a time into one output: a second is refused at once (helpers.base.locks.FolderBusy)
    with folder_lock(output.parent, what=f"running a sweep into {output.name}", name=f".{output.name}.lock"):
        return _run_sweep(definition, output, client, scheduler, workers, threads, serial, progress,
                          overwrite, keep_parts)  # fmt: skip


def _run_sweep(
    definition: SweepDefinition, output: Path, client: Any, scheduler: str | None, workers: int | None,
    threads: int, serial: bool, progress: bool, overwrite: bool, keep_parts: bool,
) -> tuple[xr.Dataset, SweepReport]:  # fmt: skip
    if output.exists() and not overwrite:  # made by the holder of the lock before us
        raise DataFileError(f"{output} exists already: pass --overwrite (overwrite=True) to replace it")
    resolved = definition.resolved()
    check_shapers(resolved.shapers, resolved.custom_shapers)
    text = resolved.to_json()
    parts = Parts(output, resolved)
    done = set(parts.open())
    todo = [c for c in range(resolved.n_chunks) if c not in done]
    desc = f"{resolved.name} ({resolved.n_runs} runs)"
    # the bar starts once the chunks can run (after connecting), so an error line is never mixed into it
    bar = tqdm(total=resolved.n_chunks, initial=len(done), unit="chunk", disable=not progress,
               file=sys.stderr, desc=desc, dynamic_ncols=True, delay=1e9)  # fmt: skip
    stats: dict[str, float] = {}
    where = "this process (serial)"
    start = time.perf_counter()

    def keep(result: dict[str, Any]) -> None:
        parts.save(result)
        for k, v in result["stats"].items():
            if k != "threads":
                stats[k] = stats.get(k, 0) + v
        bar.update(1)

    try:
        if serial or not todo:
            _start(bar)
            for c in todo:
                keep(run_chunk(text, c, threads))
        else:
            with _client_for(client, scheduler, workers) as (cl, where):
                from distributed import as_completed  # noqa: PLC0415 - Dask loads only where a sweep runs

                _start(bar)
                futures = [
                    cl.submit(run_chunk, text, c, threads, key=f"{resolved.name}-chunk-{c}", pure=False)
                    for c in todo
                ]
                try:
                    for fut in as_completed(futures):
                        keep(fut.result())
                finally:
                    cl.cancel(futures)
    except KeyboardInterrupt as exc:
        bar.close()
        signum = exc.signum if isinstance(exc, Interrupted) else 2
        n = len(parts.done())
        what = str(exc) if isinstance(exc, Interrupted) else "interrupted by Ctrl-C"
        raise SweepInterrupted(
            signum,
            f"{what}: {n} of {resolved.n_chunks} chunks are saved in {parts.folder}; run the same command "
            "again to resume (finished chunks are not recomputed)",
        ) from None
    bar.close()
    wall = time.perf_counter() - start
    ds = assemble(resolved, [parts.load(c) for c in range(resolved.n_chunks)])
    write_dataset(ds, output)
    if not keep_parts:
        parts.remove()
    refused = int((ds["status"] > 0).sum())
    report = SweepReport(
        output, resolved.n_chunks, len(done), len(todo), resolved.n_runs, wall, refused, where, stats,
        rejected=list(parts.rejected),
    )  # fmt: skip
    return ds, report
