"""coursekit: an interactive Jupyter teaching kit for genetic algorithms in computer graphics.

Two labs re-implement the systems of the seed paper ("On Artificial Intelligence and Motivation
in Computer Graphics Education"), themselves after Karl Sims:

- :mod:`coursekit.creatures` -- swimming creatures (paper section 2, Sims 1994);
- :mod:`coursekit.pictures` -- genetic pictures (paper section 3, Sims 1991);

both driven by the shared evolution engine :mod:`coursekit.ga` and graded through
:mod:`coursekit.grading`.
"""

__version__ = "0.1.0"
