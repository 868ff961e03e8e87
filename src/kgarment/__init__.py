"""kgarment: computational design of active kinesthetic garments.

Pipeline (data flows one way): body -> motions -> garment -> clutch -> sim -> design -> export.
All quantities are SI: metres, pascals, joules. Z is up, the body faces -Y.
"""

__version__ = "0.1.0"
