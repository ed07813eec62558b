"""Li et al.'s Table 4: seconds per model and shape (FP32, and MCRL in INT8), for a workload the paper does
not state.  The benchmark stage writes it beside our timings into ``inference.json`` (``paper_table4_s``),
where the report reads it: one definition, and the report needs no inference code."""

TABLE4 = {  # seconds, workload not stated
    "mcrl": {"gear": 3.2, "pentagram": 3.1, "maple_leaf": 3.9},
    "mcrl_int8": {"gear": 2.8, "pentagram": 2.9, "maple_leaf": 3.5},
    "convmixer": {"gear": 3.7, "pentagram": 3.8, "maple_leaf": 3.7},
    "convnext": {"gear": 3.7, "pentagram": 3.2, "maple_leaf": 3.8},
    "maxvit": {"gear": 3.0, "pentagram": 3.2, "maple_leaf": 4.1},
    "mlp": {"gear": 4.1, "pentagram": 4.6, "maple_leaf": 4.6},
    "cnn": {"gear": 3.7, "pentagram": 3.5, "maple_leaf": 4.3},
    "rnn": {"gear": 3.7, "pentagram": 3.8, "maple_leaf": 4.5},
    "lstm": {"gear": 3.3, "pentagram": 3.5, "maple_leaf": 4.2},
}
