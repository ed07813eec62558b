"""The published figures of Li et al. (Sensors 2024) that the report sets ours beside.

Table 2 (hyperparameters, training time in minutes), Table 3 (per cent, loss x 100 as printed),
Table 4 (seconds, workload not stated), Table 5's outcome, Table 6 and the curvature reductions of
Sec. 5.2.4; then Xie & Zhu's Table 1 and the NURBS corner paper's figures.  Typed in once here from
``../shared/seeds/``.
"""

from __future__ import annotations

# Figs. 9-11: each shape's smoothing drawn before and after, one figure per shape
PAPER_SHAPE_FIGURES = {"gear": 9, "pentagram": 10, "maple_leaf": 11}

TABLE3_COLUMNS = ("accuracy", "loss", "precision", "recall", "f1", "auc")
TABLE3 = {
    "gear": {
        "mcrl": (94.75, 14.26, 96.23, 93.52, 94.85, 97.71), "convmixer": (92.22, 18.94, 93.87, 91.06, 92.44, 96.77),
        "convnext": (93.92, 15.60, 95.54, 91.92, 93.69, 98.15), "maxvit": (93.35, 16.64, 95.23, 91.16, 93.15, 97.86),
        "mlp": (87.90, 28.61, 94.50, 82.35, 88.00, 93.55), "cnn": (93.54, 16.49, 94.79, 92.16, 93.45, 97.65),
        "rnn": (87.59, 30.54, 93.86, 88.86, 91.29, 92.77), "lstm": (92.77, 20.00, 94.09, 91.66, 92.85, 96.97),
    },
    "pentagram": {
        "mcrl": (94.98, 13.55, 96.47, 94.81, 95.63, 97.94), "convmixer": (93.91, 22.39, 94.71, 93.35, 94.02, 98.04),
        "convnext": (92.50, 20.07, 95.25, 92.77, 93.99, 96.47), "maxvit": (93.08, 18.85, 96.32, 93.79, 95.03, 96.43),
        "mlp": (87.26, 31.23, 92.26, 87.13, 89.62, 92.25), "cnn": (93.29, 17.32, 95.02, 92.29, 93.63, 97.13),
        "rnn": (86.34, 33.30, 91.27, 81.36, 86.03, 90.42), "lstm": (91.67, 20.84, 93.96, 92.72, 93.33, 96.40),
    },
    "maple_leaf": {
        "mcrl": (96.32, 9.81, 96.52, 96.19, 96.35, 98.85), "convmixer": (95.97, 10.87, 96.45, 95.47, 95.95, 98.68),
        "convnext": (95.27, 12.22, 95.34, 95.08, 95.20, 98.48), "maxvit": (95.00, 15.02, 95.41, 94.56, 94.98, 98.00),
        "mlp": (85.81, 32.66, 90.73, 80.52, 85.32, 90.69), "cnn": (94.17, 15.78, 96.42, 95.43, 95.92, 97.83),
        "rnn": (85.63, 33.78, 90.71, 80.25, 85.16, 90.01), "lstm": (94.47, 13.85, 95.03, 93.86, 94.44, 98.31),
    },
}
# lower is better for the loss; higher for every other column
LOWER_IS_BETTER = {"loss"}

# Table 2: learning rate, decay rate, decay steps, batch size, epochs, training time (minutes; the
# text calls them "units" and gives 40 for the maple leaf where the table prints 140)
TABLE2_COLUMNS = ("lr", "decay_rate", "decay_steps", "batch_size", "epochs", "minutes")
TABLE2 = {
    "gear": (0.0001, 0.9, 500, 64, 497, 212),
    "pentagram": (0.0001, 0.8, 100, 32, 203, 169),
    "maple_leaf": (0.0005, 0.8, 500, 64, 340, 140),
}
# Table 5 (gear, one random curve per category): MCRL classified all four correctly; every other
# model misclassified one of them (which one is not stated)
PAPER_MODELS = ("mcrl", "convmixer", "convnext", "maxvit", "mlp", "cnn", "rnn", "lstm")  # its rows' order
TABLE5_CORRECT = {model: 4 if model == "mcrl" else 3 for model in PAPER_MODELS}

# Xie & Zhu, Table 1, per sample-set size and "optimised sorting" (collision avoidance):
# (collisions, average empty travel of manual sorting mm, empty travel mm, time s, optimisation rate %).
XIE_ZHU_TABLE1 = {
    58: {"no": (2, 10650, 8134, 604, 23.6), "yes": (1, 10650, 8021, 544, 24.0)},
    63: {"no": (2, 11560, 9656, 601, 16.5), "yes": (1, 11560, 9132, 580, 21.0)},
    68: {"no": (2, 12193, 10373, 671, 14.9), "yes": (1, 12193, 10295, 626, 15.6)},
    73: {"no": (5, 13225, 11341, 740, 14.2), "yes": (4, 13225, 11032, 616, 16.6)},
    78: {"no": (6, 14089, 12010, 803, 14.7), "yes": (4, 14089, 11461, 714, 18.6)},
}

# The NURBS corner paper (NURBS corner smoothing, PSO and FDLS / SDLS), the figures its text gives: case 1 (W) the
# largest curvature reduction at a corner; case 2 (dress) the machining time saved against its
# refs. 20 and 21 (which we stand in for with a B-spline and a G2 Bezier transition).
NURBS_CORNER_PAPER = {"w_max_reduction_pct": 92.7, "dress_saved_vs_ref20_pct": 8.0, "dress_saved_vs_ref21_pct": 36.9}

# Li et al. (2024), Sec. 5.2.4 and Table 6
PAPER_REDUCTION = {"mean_filter": 54.0, "bezier": 67.0, "nacoa": 78.0}  # Sec. 5.2.4, per cent
PAPER_TABLE6 = {  # runtime in minutes on an RTX 4070, GPU share, Eq. 34's efficiency
    "nacoa": {"minutes": 10, "gpu_percent": 16, "efficiency": 8.4},
    "scso": {"minutes": 12, "gpu_percent": 20, "efficiency": 6.67},
    "esoa": {"minutes": 11, "gpu_percent": 18, "efficiency": 7.45},
    "avoa": {"minutes": 17, "gpu_percent": 23, "efficiency": 4.53},
}
