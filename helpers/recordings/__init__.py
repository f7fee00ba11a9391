"""The recordings of ``data/``: one run = ``<group>/<name>.csv`` + ``.json`` (``docs/recording_format.md``).

- :mod:`helpers.recordings.format`: what a recording is: the raw columns of each version, :class:`Recording`
  and the one frame shape every version loads into;
- :mod:`helpers.recordings.checks`: every key of the metadata checked against the recording's own rig (the
  schema ``metadata.schema.json`` and what ties keys together), and the samples;
- :mod:`helpers.recordings.writer`: the one writer, :func:`from_samples` (``schema_version`` 4, 1 to 4
  tendons);
- :mod:`helpers.recordings.store`: where recordings live and how they are written and read without ever
  losing one: validated names, no silent overwrite, pairs that cannot be torn (the JSON, holding the CSV's
  sha256, is written last), one writer per folder at a time, :func:`load` and :func:`catalogue`.
"""

from helpers.recordings.format import (
    TIP_COLUMNS,
    TIP_MM_COLUMNS,
    VERSION,
    Recording,
    RecordingError,
    counts_to_newtons,
)
from helpers.recordings.store import (
    RESERVED_NAMES,
    RecordingExists,
    aborted_path,
    catalogue,
    check_name,
    load,
    refuse_existing,
    reserve,
    save,
)
from helpers.recordings.writer import from_samples, nominal_calibration
from helpers.rigfile.recorded import calibration_of, recording_rig, rig_section

__all__ = [
    "RESERVED_NAMES", "TIP_COLUMNS", "TIP_MM_COLUMNS", "VERSION", "Recording",
    "RecordingError", "RecordingExists", "aborted_path", "calibration_of", "catalogue", "check_name",
    "counts_to_newtons", "from_samples", "load", "nominal_calibration",
    "refuse_existing", "recording_rig", "reserve", "rig_section", "save",
]  # fmt: skip
