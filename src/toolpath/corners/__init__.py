"""NURBS local corner smoothing (the NURBS corner paper, seed 002): the corner curve (Eq. 1-8), PSO for its
extra control points, the FDLS / SDLS surrogates, the two established transitions it is compared with, the
paper's three case paths (:mod:`~toolpath.corners.cases`) and whole paths smoothed corner by corner for the
feedrate planner.  Used by the ``corner`` stage."""
