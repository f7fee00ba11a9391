"""A commented rig file template, filled with the paper's rig (``python -m helpers rig new FILE``)."""

from __future__ import annotations

import json
import textwrap
from typing import Any

from helpers.rigfile.model import RigFile
from helpers.rigfile.schema import ARM, BOARDS, HARDWARE, REQUIRED, TENDON, Key

__all__ = ["template_text"]


def _toml(value: Any) -> str:
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)


def _comment(key: Key) -> list[str]:
    unit = "" if key.unit == "-" else f" [{key.unit}]"
    need = " (required)" if key.default is REQUIRED else ""
    text = f"{key.doc}{unit}{need}"
    return ["# " + line for line in textwrap.wrap(text, 106)]


def template_text(paper: RigFile, name: str = "my-rig") -> str:
    """The template: every key with its meaning and unit, set to the paper's rig's value.

    Parameters
    ----------
    paper : RigFile
        The rig whose values fill the template (the paper's).
    name : str
        The new rig's name.
    """
    lines = [
        "# A rig file: your rig's hardware, arm and boards (docs/rig_file.md lists every key).",
        "# Filled with the paper's rig: change what differs on yours, then run",
        "#   python -m helpers rig check THIS_FILE",
        "# Keys marked (required) must be there; the others may be deleted to take the value shown.",
        "schema_version = 1",
        f"name = {json.dumps(name)}",
        'description = ""',
    ]
    for table, keys in (("hardware", HARDWARE), ("arm", ARM), ("boards", BOARDS)):
        values = getattr(paper, table)
        lines += ["", f"[{table}]"]
        for key in keys:
            lines += _comment(key)
            lines.append(f"{key.name} = {_toml(getattr(values, key.name))}")
    lines += [
        "",
        "# Tendons: none = one tendon at 0 degrees at [arm] cable_offset_mm with [hardware]'s stepper and",
        "# load cell. Up to four [[tendon]] tables; absent keys take [hardware]'s and [arm]'s values.",
        "# For example:",
    ]
    for angle in (0.0, 180.0):
        lines += ["# [[tendon]]", f"# angle_deg = {angle!r}"]
    lines.append("# Keys of a [[tendon]] table:")
    for key in TENDON:
        unit = "" if key.unit == "-" else f" [{key.unit}]"
        lines.append(f"#   {key.name}: {key.doc}{unit}"[:110])
    return "\n".join(lines) + "\n"
