"""The paper's part: its printed numbers and hardware, the linear model, identification, its shapers.

``numbers`` (the paper's printed values), ``hardware``, ``backbone``, ``modes``, ``model``, ``identify``,
``shapers`` (ZV and ZVD), ``profiles``, ``metrics`` (Table II) and ``calibration`` (the load cell's);
``docs/architecture.md`` draws the wings around it.
"""
