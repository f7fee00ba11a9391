"""Reading a finished sweep: its NetCDF file as an xarray Dataset (needs neither the rig nor Dask)."""

from __future__ import annotations

import os
from pathlib import Path

import xarray as xr

from helpers.base.jsonfile import DataFileError, MissingDataError
from helpers.research.sweep.schema import check_attrs

__all__ = ["load_sweep"]


def load_sweep(path: str | os.PathLike) -> xr.Dataset:
    """Read a finished sweep's dataset (into memory; the file is closed again).

    Raises
    ------
    helpers.base.jsonfile.MissingDataError
        If there is no such file (the message says how to make it).
    helpers.base.jsonfile.DataFileError
        If it is not a sweep's NetCDF file.
    """
    path = Path(path)
    if not path.exists():
        raise MissingDataError(
            f"{path} is missing: run the sweep (`python -m helpers sweep run ...`, docs/sweeps.md)"
        )
    try:
        with xr.open_dataset(path, engine="scipy") as ds:
            out = ds.load()
    except (OSError, ValueError, TypeError) as exc:
        raise DataFileError(f"{path}: not a readable NetCDF file ({exc})") from None
    try:
        check_attrs(dict(out.attrs))  # the one schema of a dataset's attributes (.schema)
    except ValueError as exc:
        raise DataFileError(f"{path}: not a sweep's dataset: attribute {exc}") from None
    missing = [v for v in ("residual_pct", "status") if v not in out.data_vars]
    if missing:
        raise DataFileError(f"{path}: not a sweep's dataset: no variable {missing[0]}")
    return out
