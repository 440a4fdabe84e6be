"""Grading for coursekit exercises (seed paper section 4: students' operators, checked, drive the real systems).

- :func:`check` -- formative feedback inside an exercise notebook, then :func:`hint` for a hint
  ladder (:mod:`.formative`);
- :mod:`.checks` -- the registry of checks shared by formative and summative grading;
- :mod:`.runner` -- the only code that calls student functions (forked, bounded, plain data out);
- :mod:`.grader` -- ``coursekit grade``: isolated summative grading, with :mod:`.sandbox` (bubblewrap),
  :mod:`.supervisor` (limits and processes, from outside), :mod:`.executor` (the grading child),
  :mod:`.channel` (what the child sends back) and :mod:`.report` (summary, Gradescope JSON);
- :mod:`.authoring` -- ``coursekit exercises build|check``: exercises generated from solutions.
"""

from coursekit.grading.formative import check, evaluate, hint

__all__ = ["check", "evaluate", "hint"]
