"""The recordings of ``data/``: one run = ``<group>/<name>.csv`` + ``.json`` (``docs/recording_format.md``).

- :mod:`helpers.recordings.format`: what a recording is: the columns, the metadata and its validation field by
  field, :class:`Recording` and the derived columns;
- :mod:`helpers.recordings.store`: where recordings live and how they are written and read without ever
  losing one: validated names, no silent overwrite, pairs that cannot be torn (the JSON, holding the CSV's
  sha256, is written last), one writer per folder at a time, :func:`load` and :func:`catalogue`.
"""

from helpers.recordings.format import (
    SCHEMA_VERSION,
    Recording,
    RecordingError,
    counts_to_newtons,
    empty_frame,
    frame_from_rows,
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
from helpers.rigfile.recorded import recording_rig, rig_section

__all__ = [
    "RESERVED_NAMES",
    "SCHEMA_VERSION",
    "Recording",
    "RecordingError",
    "RecordingExists",
    "aborted_path",
    "catalogue",
    "check_name",
    "counts_to_newtons",
    "empty_frame",
    "frame_from_rows",
    "load",
    "refuse_existing",
    "recording_rig",
    "reserve",
    "rig_section",
    "save",
]
