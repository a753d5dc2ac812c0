#!/usr/bin/python3
"""Full-precision oracle: runs LinuxCNC's Python `gcode` module (the rs274ngc interpreter
behind AXIS) on a program and prints its canonical motion calls, one per line, with
repr() doubles.

Usage: /usr/bin/python3 gcode_oracle.py prog.ngc params.var

The program starts in G21 (mm), as rs274 does.

The module reports lengths in inches (AXIS's internal unit) whatever G20/G21 says, so
every length is multiplied by 25.4 here: the output is in millimetres, in the program
coordinate system (G5x/G92 offsets not applied, as with rs274). Angles (A, B, C) are
degrees. Output lines:
  traverse x y z a b c
  feed x y z a b c
  arc first_end second_end first_centre second_centre rotation axis_end a b c
  g5x index x y z a b c
  g92 x y z a b c
  rot degrees        (SET_XY_ROTATION: the active system's rotation about Z)
  plane n            (1 = XY, 2 = YZ, 3 = XZ)
  dwell seconds
  result code line   (line is 1-based; code > gcode.MIN_ERROR is an error)
"""
import sys

import gcode

MM = 25.4


def fmt(v):
    return repr(float(v))


def lengths(vals):
    return [v * MM for v in vals]


class Canon:
    def __init__(self, var_file):
        self.parameter_file = var_file

    # Queries made by the interpreter.
    def get_external_length_units(self):
        return 1.0

    def get_external_angular_units(self):
        return 1.0

    def get_axis_mask(self):
        return 0x1FF

    def get_block_delete(self):
        return False

    def check_abort(self):
        return False

    def get_tool(self, idx):
        return (idx,) + (0.0,) * 12 + (0,)

    def next_line(self, state):
        pass

    def out(self, name, vals):
        print(name, " ".join(fmt(v) for v in vals))

    def straight_traverse(self, x, y, z, a, b, c, u, v, w):
        self.out("traverse", lengths([x, y, z]) + [a, b, c])

    def straight_feed(self, x, y, z, a, b, c, u, v, w):
        self.out("feed", lengths([x, y, z]) + [a, b, c])

    def arc_feed(self, fe, se, fc, sc, rot, ae, a, b, c, u, v, w):
        self.out("arc", lengths([fe, se, fc, sc]) + [rot] + lengths([ae]) + [a, b, c])

    def set_g5x_offset(self, index, x, y, z, a, b, c, u=0, v=0, w=0):
        self.out("g5x", [index] + lengths([x, y, z]) + [a, b, c])

    def set_g92_offset(self, x, y, z, a, b, c, u=0, v=0, w=0):
        self.out("g92", lengths([x, y, z]) + [a, b, c])

    def set_xy_rotation(self, theta):
        self.out("rot", [theta])

    def set_plane(self, plane):
        print("plane", plane)

    def dwell(self, seconds):
        self.out("dwell", [seconds])

    def __getattr__(self, name):
        # Every other canonical call (comments, feed rate, spindle...) is ignored.
        if name.startswith("__"):
            raise AttributeError(name)
        return lambda *args: None


def main():
    prog, var_file = sys.argv[1], sys.argv[2]
    result, line = gcode.parse(prog, Canon(var_file), "G21", "")
    print("result", result, line, int(result > gcode.MIN_ERROR))
    if result > gcode.MIN_ERROR:
        print("message", gcode.strerror(result))


main()
