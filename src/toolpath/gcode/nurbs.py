"""NURBS motion, in both forms CAM posts write, turned into chords within the reader's chord tolerance.

**G5.2 / G5.3 (LinuxCNC).**  ``G5.2 [X.. Y..] [P<weight>] [L<order>]`` opens a block whose first control
point is where the tool stands (weight 1, or the P of a ``G5.2 P..`` line without X and Y); each line
``X.. Y.. [P..]`` after it adds a control point (a missing axis modal from the previous point, weight
1 by default); ``G5.3`` closes the block and runs the curve.  The order L is 3 unless given (2-10).
The knots are LinuxCNC's (``nurbs_G5_knot_vector_creator``): clamped and uniform, ``order`` zeros,
then 1, 2, .., ``n - order + 1``, then ``order`` times ``n - order + 2`` for control points 0..n, so
the curve runs from the first control point to the last.  XY plane, absolute coordinates (G90).

**G6.2 (Fanuc style).** A block starts with ``G6.2 P<order> K<knot> X.. Y.. [Z..] [R<weight>] [F..]``
(the first control point, which must be where the tool stands); each following line with a K word is
either a control point (``K X Y [Z] [R]``, missing axes modal from the previous point, weight 1 by
default) or, at the end, a bare knot (``K``). The first line with words but no K ends the block, as does
the end of the program. There are ``control points + order`` knots, non-decreasing; the curve runs over
``[knot[order - 1], knot[n]]``. The block's points belong to its last K line; afterwards no motion mode
is in effect (the next move must say G0/G1/G2/G3), after either form. Absolute coordinates (G90) only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from toolpath.gcode.arcs import MAX_ARC_POINTS
from toolpath.gcode.program import MM_PER_INCH, Motion


@dataclass
class NurbsBlock:
    """A G6.2 block being read: control points (mm, reader frame), weights and knots so far."""

    order: int
    first_line: int
    points: list[np.ndarray] = field(default_factory=list)
    weights: list[float] = field(default_factory=list)
    knots: list[float] = field(default_factory=list)
    last_line: int = 0
    kind: str = "G6.2"  # or "G5.2"
    closed: bool = False  # a G5.2 block: its G5.3 was read


def linuxcnc_knots(count: int, order: int) -> list[float]:
    """The knots LinuxCNC gives a G5.2 block of ``count`` control points: clamped, uniform, whole."""
    n = count - 1
    return [0.0] * order + [float(i) for i in range(1, n - order + 2)] + [float(n - order + 2)] * order


def _chord_gaps(curve, t: np.ndarray) -> np.ndarray:
    """Distance from the curve's point at each parameter midpoint to the chord between its neighbours."""
    a, b = curve(t[:-1]), curve(t[1:])
    mid = curve(0.5 * (t[:-1] + t[1:]))
    ab, am = b - a, mid - a
    length2 = np.einsum("ij,ij->i", ab, ab)
    s = np.clip(np.einsum("ij,ij->i", am, ab) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    return np.linalg.norm(am - s[:, None] * ab, axis=1)


def evaluate_spline(knots: np.ndarray, coefficients: np.ndarray, degree: int, t: np.ndarray) -> np.ndarray:
    """The B-spline of ``degree`` with ``knots`` and ``coefficients`` (rows) at parameters ``t`` inside
    ``[knots[degree], knots[n]]`` (n the number of coefficients), by de Boor's algorithm; the end
    parameter belongs to the last non-empty knot span.  NumPy only: reading G-code needs no SciPy."""
    n, k = len(coefficients), degree
    span = np.clip(np.searchsorted(knots, t, side="right") - 1, k, n - 1)
    last = max(i for i in range(k, n) if knots[i] < knots[i + 1])
    span = np.where(t >= knots[n], last, np.minimum(span, last))
    d = [coefficients[span - k + j] for j in range(k + 1)]  # each (len(t), dims)
    for r in range(1, k + 1):
        for j in range(k, r - 1, -1):
            left, right = knots[span - k + j], knots[span + 1 + j - r]
            alpha = ((t - left) / (right - left))[:, None]
            d[j] = (1.0 - alpha) * d[j - 1] + alpha * d[j]
    return d[k]


def discretise(block: NurbsBlock, chord_tolerance: float) -> np.ndarray:
    """Points along the block's curve, after its first, every chord within ``chord_tolerance`` of the
    curve at its parameter midpoint (chords halved until they are).

    Raises
    ------
    ValueError
        For a block that does not define a NURBS curve, saying why.
    """
    n, order = len(block.points), block.order
    knots = np.asarray(block.knots, float)
    if n < order:
        raise ValueError(f"a NURBS of order {order} needs at least {order} control points, not {n}")
    if len(knots) != n + order:
        raise ValueError(f"a NURBS of order {order} with {n} control points needs {n + order} knots (K words), "
                         f"not {len(knots)}")
    if np.any(np.diff(knots) < 0):
        raise ValueError("the knots (K words) of a NURBS must not decrease")
    if not knots[order - 1] < knots[n]:
        raise ValueError("the knots leave the NURBS no parameter range (knot[order - 1] = knot[n])")
    weights = np.asarray(block.weights, float)
    if np.any(weights <= 0):
        raise ValueError("NURBS weights (R words) must be positive")
    homogeneous = np.hstack([np.asarray(block.points) * weights[:, None], weights[:, None]])
    def curve(t: np.ndarray) -> np.ndarray:
        h = evaluate_spline(knots, homogeneous, order - 1, t)
        return h[:, :3] / h[:, 3:]

    lo, hi = knots[order - 1], knots[n]
    inner = np.unique(knots[(knots > lo) & (knots < hi)])
    t = np.unique(np.concatenate([np.linspace(lo, hi, 4 * (n - order + 1) + 1), inner]))
    while True:
        gaps = _chord_gaps(curve, t)
        wide = gaps > chord_tolerance
        if not wide.any():
            break
        t = np.sort(np.concatenate([t, 0.5 * (t[:-1] + t[1:])[wide]]))
        if len(t) > MAX_ARC_POINTS:
            raise ValueError(f"the NURBS needs more than {MAX_ARC_POINTS:,} chords at a chord tolerance of "
                             f"{chord_tolerance:g} mm")
    return curve(t)[1:]


class NurbsMotion:
    """The reader's handling of G5.2 and G6.2 blocks (mixed into its interpreter, whose state it uses)."""

    def _open_nurbs(self, motion: int | None, values: dict[str, float], lineno: int) -> None:
        """``G6.2 P<order> K X Y [Z] [R]``: the first control point, where the tool stands."""
        if motion is not None:
            raise self.fail(lineno, f"G6.2 and G{motion} on one line")
        if not self.absolute:
            raise self.fail(lineno, "G6.2 (NURBS) needs absolute coordinates (G90)")
        order = values.get("P")
        if order is None or order != int(order) or not 2 <= order <= 10:
            raise self.fail(lineno, "G6.2 needs P, the order of the NURBS: a whole number 2-10")
        if "K" not in values:
            raise self.fail(lineno, "G6.2 needs K, the first knot")
        start = self._target(values)
        if np.abs(start - self.pos).max() > self.opt.chord_tolerance:
            raise self.fail(lineno, f"G6.2: the first control point {tuple(np.round(start, 6))} is not where the "
                                    f"tool stands {tuple(np.round(self.pos, 6))}")
        self.nurbs = NurbsBlock(int(order), lineno, last_line=lineno)
        self._nurbs_point(values, self.pos.copy(), lineno)
        self.motion = None

    def _nurbs_point(self, values: dict[str, float], point: np.ndarray, lineno: int) -> None:
        weight = values.get("R", 1.0)
        if not weight > 0:
            raise self.fail(lineno, f"NURBS weight R{weight:g} must be positive")
        self.nurbs.points.append(point)
        self.nurbs.weights.append(weight)
        self.nurbs.knots.append(values["K"])

    def _nurbs_line(self, words, lineno: int) -> None:  # noqa: ANN001 - the line's words
        """A line of a G6.2 block: ``K X Y [Z] [R]`` (a control point) or a bare ``K`` (a closing knot),
        either one perhaps led by G6.2 again (LinuxCNC's examples write ``G6.2 K14`` closing knots)."""
        values = {w.letter: w.value for w in words if w.letter != "G"}
        extra = sorted({w.letter for w in words if not (w.letter == "G" and round(w.value, 1) == 6.2)} - set("KXYZRNF"))
        if extra:
            raise self.fail(lineno, f"a G6.2 block line holds only K, X, Y, Z, R (N, F) words (G6.2 repeated), "
                                    f"not {', '.join(extra)}")
        if "F" in values:
            self.feed = values["F"] * (MM_PER_INCH if self.inch else 1.0)
        block = self.nurbs
        block.last_line = lineno
        if any(a in values for a in "XYZR"):
            if len(block.knots) > len(block.points):
                raise self.fail(lineno, "a G6.2 control point after the closing knots")
            scale, point = MM_PER_INCH if self.inch else 1.0, block.points[-1].copy()
            for i, a in enumerate("XYZ"):
                if a in values:
                    point[i] = values[a] * scale + self.offset[i]
            self._nurbs_point(values, point, lineno)
        else:
            block.knots.append(values["K"])

    def _open_g5(self, motion: int | None, values: dict[str, float], lineno: int) -> None:
        """``G5.2 [X Y] [P] [L]``: a LinuxCNC NURBS block, from where the tool stands."""
        if motion is not None:
            raise self.fail(lineno, f"G5.2 and G{motion} on one line")
        if not self.absolute:
            raise self.fail(lineno, "G5.2 (NURBS) needs absolute coordinates (G90)")
        order = values.get("L", 3.0)
        if order != int(order) or not 2 <= order <= 10:
            raise self.fail(lineno, f"G5.2 L{order:g}: the order of the NURBS must be a whole number 2-10")
        self.nurbs = NurbsBlock(int(order), lineno, last_line=lineno, kind="G5.2")
        self.motion = None
        in_plane, off_plane = self._g5_axes()
        placed = any(a in values for a in in_plane)
        self.nurbs.points.append(self.pos.copy())
        self.nurbs.weights.append(1.0 if placed else self._g5_weight(values, lineno))
        if placed:
            self._g5_point(values, lineno)
        elif off_plane in values:
            raise self.fail(lineno, f"a G5.2 NURBS lies in the {in_plane} plane: no {off_plane} inside the block")

    def _g5_axes(self) -> tuple[str, str]:
        """The axes of the selected plane (G17 XY; G18 XZ and G19 YZ where the reader passes through)
        and the one off it: LinuxCNC draws a G5.2 block in the selected plane."""
        in_plane = {18: "XZ", 19: "YZ"}.get(getattr(self, "plane", 17), "XY")
        return in_plane, next(a for a in "XYZ" if a not in in_plane)

    def _g5_weight(self, values: dict[str, float], lineno: int) -> float:
        weight = values.get("P", 1.0)
        if not weight > 0:
            raise self.fail(lineno, f"NURBS weight P{weight:g} must be positive")
        return weight

    def _g5_point(self, values: dict[str, float], lineno: int) -> None:
        in_plane, off_plane = self._g5_axes()
        if off_plane in values:
            raise self.fail(lineno, f"a G5.2 NURBS lies in the {in_plane} plane: no {off_plane} inside the block")
        scale, point = MM_PER_INCH if self.inch else 1.0, self.nurbs.points[-1].copy()
        for i, a in enumerate("XYZ"):
            if a in values:
                point[i] = values[a] * scale + self.offset[i]
        self.nurbs.points.append(point)
        self.nurbs.weights.append(self._g5_weight(values, lineno))

    def _g5_line(self, words, lineno: int) -> None:  # noqa: ANN001 - the line's words
        """A line of a G5.2 block: ``X Y [P]`` (a control point) or ``G5.3`` (the end: the curve runs)."""
        values = {w.letter: w.value for w in words if w.letter != "G"}
        codes = [round(w.value, 1) for w in words if w.letter == "G"]
        extra = sorted({w.letter for w in words} - set("XYZPNFG"))
        if extra or any(code != 5.3 for code in codes):
            raise self.fail(lineno, "a G5.2 block line holds only X, Y, P (N, F) words, and G5.3 ends it; not "
                                    + ", ".join(extra + [f"G{code:g}" for code in codes if code != 5.3]))
        if "F" in values:
            self.feed = values["F"] * (MM_PER_INCH if self.inch else 1.0)
        if codes:
            if any(a in values for a in "XYZP"):
                raise self.fail(lineno, "G5.3 ends the NURBS block on a line of its own (no X, Y, P)")
            block = self.nurbs
            block.last_line, block.closed = lineno, True
            block.knots = linuxcnc_knots(len(block.points), block.order)
            self.close_nurbs(lineno)
        elif any(a in values for a in "XYZ"):
            self._g5_point(values, lineno)
        elif values.keys() - {"N", "F"}:
            in_plane = self._g5_axes()[0]
            raise self.fail(lineno, f"a G5.2 control point needs {in_plane[0]} or {in_plane[1]}")

    def close_nurbs(self, last_row: int) -> None:
        """End the open block: its chords become points of its last line (the last K line, or G5.3);
        the rows of the text being read from that line to ``last_row`` (program line numbers) get the
        curve's end."""
        block, self.nurbs = self.nurbs, None
        if block.kind == "G5.2" and not block.closed:
            raise self.fail(block.first_line, "the G5.2 block that starts here is not closed by G5.3")
        try:
            pts = discretise(block, self.opt.chord_tolerance)
        except ValueError as exc:
            raise self.fail(block.last_line, f"{block.kind} block from line {block.first_line}: {exc}") from None
        if len(pts):
            self._emit(pts, Motion.ARC, block.last_line)
            self.pos = pts[-1].copy()
        if self.table is not None:
            first, stop = max(block.last_line - self.base, 0), last_row - self.base + 1
            if stop > first:
                self.table.position[first:stop] = self.pos
