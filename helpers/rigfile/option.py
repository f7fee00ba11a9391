"""The commands' ``--rig FILE`` option, taken off the command line before any command's module loads.

:mod:`helpers.__main__` calls :func:`take_rig_option` and then :func:`use`, because the commands' modules
read the selected rig when they are imported. Standard library and :mod:`helpers.rigfile` only.
"""

from __future__ import annotations

import os

from helpers.rigfile import ENV_VAR, RigFile, load, resolve


def take_rig_option(argv: list[str]) -> tuple[list[str], str | None]:
    """Remove ``--rig FILE`` (or ``--rig=FILE``) from a command line; return the rest and ``FILE``.

    Arguments after ``--`` are left alone. A ``--rig`` without a value is refused (``ValueError``).
    """
    rest: list[str] = []
    value: str | None = None
    i = 0
    while i < len(argv):
        arg = argv[i]
        if arg == "--":
            rest += argv[i:]
            break
        if arg == "--rig":
            if i + 1 >= len(argv) or argv[i + 1].startswith("-"):
                raise ValueError("--rig needs a rig file (a path, or a shipped rig's name such as paper)")
            value = argv[i + 1]
            i += 2
            continue
        if arg.startswith("--rig="):
            value = arg.split("=", 1)[1]
            if not value:
                raise ValueError("--rig needs a rig file (a path, or a shipped rig's name such as paper)")
            i += 1
            continue
        rest.append(arg)
        i += 1
    return rest, value


def use(name_or_path: str | os.PathLike[str]) -> RigFile:
    """Select a rig for this process and the processes it starts: check it, then set ``$HELPERS_RIG``.

    Call before the modules that read the rig load (``helpers.paper.hardware`` reads it once, on import).
    """
    path = resolve(name_or_path)
    rig = load(path)
    os.environ[ENV_VAR] = str(path.resolve())
    return rig
