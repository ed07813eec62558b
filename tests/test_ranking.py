"""Table 3d: the ranking of every network across (shape, seed) blocks with autorank."""

import numpy as np

from toolpath.reports import ranking


def summary(values, degenerate=0):
    return {"replicates": {"degenerate": degenerate, "test": {"accuracy": {
        "per_seed": {f"seed{k}": v for k, v in enumerate(values)}}}}}


def test_blocks_pair_shapes_and_seeds_and_leave_degenerate_networks_out():
    metrics = {"gear": {"a": summary([0.9, 0.91]), "b": summary([0.8, 0.82]), "c": summary([0.6, 0.6], 1)},
               "pentagram": {"a": summary([0.95, 0.96]), "b": summary([0.85, 0.86]), "c": summary([0.7, 0.7])}}
    blocks, dropped = ranking.accuracy_blocks(metrics, ["a", "b", "c"])
    assert blocks == {"a": [0.9, 0.91, 0.95, 0.96], "b": [0.8, 0.82, 0.85, 0.86]} and dropped == ["c"]
    assert ranking.rank(blocks) is None  # 4 blocks: too few for the test
    table = ranking.ranking_table(None, blocks, dropped)
    assert table.rows == [] and "Not ranked" in table.notes[0] and "c" in table.notes[0]


def test_a_clear_order_is_ranked_and_close_networks_are_grouped():
    rng = np.random.default_rng(0)
    blocks = {m: list(0.9 + 0.02 * k + rng.normal(0, 0.002, 9)) for k, m in enumerate(["low", "mid", "top"])}
    blocks["twin"] = [v + 0.0001 * (-1) ** i for i, v in enumerate(blocks["top"])]
    result = ranking.rank(blocks)
    table = ranking.ranking_table(result, blocks, [])
    assert [r[0] for r in table.rows[2:]] == ["mid", "low"]  # best first: rank 1 is the highest accuracy
    assert {table.rows[0][0], table.rows[1][0]} == {"top", "twin"}
    assert "twin" in dict((r[0], r[3]) for r in table.rows)["top"]  # the test cannot tell the twins apart
    assert "the networks differ" in table.notes[0]
    assert ranking.cd_figure(result) is not None
