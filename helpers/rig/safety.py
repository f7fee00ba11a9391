"""The safety limits checked before any byte is sent, as the rig's users import them (``docs/safety.md``).

They are :mod:`helpers.live.safety`'s (the small driver of the live cells checks the same limits); this module
names them for the rig's modules, the commands and the research.
"""

from helpers.live.safety import SafetyError, check_programme, check_request

__all__ = ["SafetyError", "check_programme", "check_request"]
