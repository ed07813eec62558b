"""mealpy's Sand Cat swarm optimisation (SCSO) with its generation computed over the whole swarm at once.

``mealpy.swarm_based.SCSO.OriginalSCSO.evolve`` loops over agents and dimensions in Python and draws a
roulette wheel over 360 angles per coordinate: on our 96-dimensional windows it ran 12x slower than
the other mealpy baselines at the same number of evaluations (5 s per window), most of the optimise
stage's time.  :class:`VectorisedSCSO` keeps mealpy's equations, its angle wheel (indices 0-359 used
as radians, as mealpy does), budget and bookkeeping; only the order of its random draws differs, so
a seed gives a different but equally distributed run.  Imports mealpy (installed ``--no-deps``).
"""

from __future__ import annotations

import numpy as np
from mealpy.swarm_based.SCSO import OriginalSCSO


class VectorisedSCSO(OriginalSCSO):
    """OriginalSCSO (Seyyedabbasi and Kiani 2022, as mealpy 3.0.3 implements it), one generation per array op."""

    def evolve(self, epoch: int) -> None:
        guides_r = self.ss - (self.ss * epoch / self.epoch)
        positions = np.array([agent.solution for agent in self.pop])
        count, dims = positions.shape
        r = self.generator.random(count) * guides_r
        phase = (2 * guides_r) * self.generator.random(count) - guides_r  # mealpy's R: |R| <= 1 attacks
        wheel = np.cumsum(self.pp / self.pp.sum())
        teta = np.searchsorted(wheel, self.generator.random((count, dims)), side="right")
        best = self.g_best.solution
        attack = best - r[:, None] * np.abs(self.generator.random((count, dims)) * best - positions) * np.cos(teta)
        partner = (self.generator.random((count, dims)) * count).astype(int)
        search = r[:, None] * (positions[partner, np.arange(dims)] - self.generator.random((count, dims)) * positions)
        moved = np.where((np.abs(phase) <= 1)[:, None], attack, search)
        pop_new = []
        for row in moved:
            position = self.correct_solution(row)
            agent = self.generate_empty_agent(position)
            if self.mode not in self.AVAILABLE_MODES:
                agent.target = self.get_target(position)
            pop_new.append(agent)
        self.pop = self.update_target_for_population(pop_new)
