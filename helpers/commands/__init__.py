"""The command line's wing: the commands of ``python -m helpers <command>``.

The dispatcher is ``helpers.__main__``; each command module here provides ``add_arguments(parser)`` and
``run(args)`` (``docs/architecture.md``).
"""
