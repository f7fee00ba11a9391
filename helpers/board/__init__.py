"""The boards' side of the link, host-side.

The line protocol, its CRC-8, the stepper's programmes and the reference of the stepper board's streaming
shaper (``docs/architecture.md``).
"""
