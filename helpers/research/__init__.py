"""The research wing: what goes beyond the paper.

Mode maps, designs from them, robustness, shaper tuning, families beyond ZV/ZVD, streams of arbitrary
motion, sweeps. It imports the core; the core never imports it (``docs/architecture.md``).
"""
