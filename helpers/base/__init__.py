"""The core's utilities: paths, argument checks, the JSON files, the plot style, signals, locks, notebooks.

Nothing here knows the paper, the rig or the twin (``docs/architecture.md``).
"""
