"""coursekit.operations.CountOperations: operations, arithmetic and memory traffic, by known values."""

import torch

from coursekit.operations import CountOperations


def test_elementwise_products_and_reductions_have_their_textbook_counts():
    a, b = torch.ones(3, 5, dtype=torch.float64), torch.ones(3, 5, dtype=torch.float64)
    with CountOperations() as ops:
        a + b  # 15 additions; reads 2 x 15 doubles, writes 15
    assert (ops.count, ops.flops, ops.bytes) == (1, 15, 3 * 15 * 8)
    x, y = torch.ones(2, 3, 4), torch.ones(2, 4, 5)
    with CountOperations() as ops:
        torch.bmm(x, y)  # 2 products of 3x4 by 4x5: 2 * 2 * 3 * 4 * 5 multiply-adds counted twice
    assert (ops.count, ops.flops, ops.bytes) == (1, 240, (24 + 40 + 30) * 4)
    with CountOperations() as ops:
        torch.ones(10).sum()  # the ones, then 10 additions
    assert ops.count == 2 and ops.flops == 10 + 10


def test_views_launch_nothing_and_cost_nothing():
    x = torch.ones(4, 6)
    with CountOperations() as ops:
        x.reshape(24)[3:9].unsqueeze(0).expand(5, 6)
    assert (ops.count, ops.flops, ops.bytes) == (0, 0, 0)
