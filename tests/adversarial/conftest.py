# The notebooks here attack the grader (infinite loops, os._exit, segfaults, memory hogs, daemons
# that overwrite files). They are run only by tests/test_grading_integrity.py, inside the
# grader's sandbox -- never directly by nbmake.
collect_ignore_glob = ["*.ipynb"]
