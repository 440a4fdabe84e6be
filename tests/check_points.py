"""A rule shared by the grading tests of every exercise whose checks have a *point*
(:func:`coursekit.grading.checks.properties.point`): the operator's definition weighs half the check."""

from coursekit.grading import checks


def assert_a_point_weighs_half(name: str) -> None:
    check = checks.get(name)
    weights = dict(check.weights)
    total = 1 + sum(weights.get(p, 1) for p, _ in check.props)  # "runs" counts 1
    assert [p for p, _ in check.props if 2 * weights.get(p, 1) == total], check.weights
