"""The paper's part: its printed numbers and hardware, the linear model, identification, its shapers.

``numbers`` (the paper's printed values), ``backbone``, ``modes``, ``model``, ``identify``, ``shapers``
(ZV and ZVD), ``profiles``, ``scenarios`` (the paper's on a rig), ``metrics`` (Table II), ``calibration`` and
``tension`` (the load cell's); ``docs/architecture.md`` draws the wings around it.
"""
