"""The commands' ``--rig FILE`` option, taken off the command line before any command's module loads.

:mod:`helpers.__main__` calls :func:`take_rig_option` and then :func:`helpers.rigfile.use`, because the
commands' modules read the selected rig when they are imported. Standard library only.
"""

from __future__ import annotations


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
