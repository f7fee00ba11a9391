"""The spatial twin: an arc chain bending about two axes and twisting, pulled by up to four tendons.

Physics only, like :mod:`helpers.virtual`: the rig description (:mod:`~helpers.virtual.spatial.rig`), the
arm in numpy (:mod:`~helpers.virtual.spatial.chain`), its statics and small vibrations
(:mod:`~helpers.virtual.spatial.statics`), the map of its modes over bend direction and magnitude
(:mod:`~helpers.virtual.spatial.direction_map`), and, for time, the compiled integrator
(:mod:`~helpers.virtual.spatial._kernel`) behind :class:`~helpers.virtual.spatial.plant.SpatialPlant` and
:func:`~helpers.virtual.spatial.simulate.simulate_spatial`. ``docs/spatial_twin.md`` documents the model,
every assumed parameter and the oracles.
"""
