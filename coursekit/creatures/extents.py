"""The size limits of a creature's parts, below everything that reads them (paper section 2.3).

Genotype sizes, expanded bodies (:mod:`coursekit.creatures.body`) and the water's stiffness bound
(:func:`coursekit.creatures.physics.water.max_drag_rate`) all read these two numbers; kept here,
with no imports, so none of them has to import another for them.
"""

#: The thinnest a part may be (half extent, metres): paper-thin flippers are stiff for any
#: explicit integrator and an exploit in the literature (see reference/creatures.md).
MIN_HALF_EXTENT = 0.025
#: The largest a part may be (half extent, metres); genotype sizes and expanded parts stay within both.
MAX_HALF_EXTENT = 1.0
