"""The ArcWelder benchmark's explicit copy: the same path, spelled so ArcWelder can weld it."""

from toolpath.bench.arcs import deviation, explicit_copy

PROGRAM = """G21 G90 G17
#<feed> = 70
G0 X0 Y0
G01 X1 Y0 F100
X2 Y0.1
G3 X3 Y1.1 I0 J1 F#<feed>
G1 X[1 + 3] Y1.1 (a comment)
M30
"""


def test_the_explicit_copy_states_every_motion_mode_and_keeps_the_path():
    copy = explicit_copy(PROGRAM).splitlines()
    assert copy[1] == "(#<feed> = 70)"               # an assignment becomes a comment
    assert copy[3].startswith("G1 X1 Y0")           # G01 -> G1
    assert copy[4] == "G1 X2 Y0.1"                  # a modal move states its mode
    assert copy[5].startswith("G3 X3.000000 Y1.100000") and "I0 J1" in copy[5] and copy[5].endswith("F70")
    assert copy[6].startswith("G1 X4.000000 Y1.100000")
    assert deviation(PROGRAM, "\n".join(copy) + "\n") <= 1e-9
    assert deviation(PROGRAM, PROGRAM.replace("X2 Y0.1", "X2 Y0.2")) > 0.05  # the measure sees a moved point
