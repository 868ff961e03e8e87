"""Problem files the tests share (TOML text)."""

# the smallest clutched design problem: the right arm sleeve at subdivision 0, elbow flexion,
# its one outer-elbow clutch; the reference material preset (fast, contrasting); tests add
# their own [design] and [solver] sections
TINY_SLEEVE = """
[garment]
template = "arm_sleeve.right"
subdivision = 0
[motions]
use = ["arm_flexion.right"]
[clutches]
layout = "arm_flexion"
[materials]
preset = "reference"
"""
