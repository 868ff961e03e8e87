"""The studio: an interactive web page (viser) for designing kinesthetic garments.

View the body and garment in any motion, place clutches and paint reinforcement or
attachments by hand, simulate and compare designs, run and scrub automatic designs.
The logic lives in plain modules tested without a browser; only :mod:`.app` and
:mod:`.panel` talk to viser:

==============  ======================================================================
``brush``       ray picks on the garment, brush footprints, coverage
``placement``   clutch specs from clicked points or landmarks; move, aim, select
``state``       the edited layers (design, attachments, clutches, budget) with undo
``session``     save/load a session folder; open problem files, runs and sessions
``runs``        run folders: compatibility, iterations, progress picture
``evaluate``    simulate a design: rho ON/OFF and equilibria per motion
``optimise``    BESO from the page into a normal run folder
``jobs``        background threads that report, stop and fail without losing edits
``view``        poses, strain, colours
``app/panel``   the viser page (``kgarment studio``)
==============  ======================================================================
"""
