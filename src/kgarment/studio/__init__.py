"""The studio: an interactive web page (viser) for designing kinesthetic garments.

View the body and garment in any motion, place clutches and paint reinforcement or
attachments by hand, simulate and compare designs, run and scrub automatic designs.
The logic lives in plain modules tested without a browser; only :mod:`.app`,
:mod:`.scene` and :mod:`.panel` talk to viser. Imports go down this table, never up:

===============  =====================================================================
``brush``        ray picks on the garment, brush footprints, coverage
``placement``    clutch specs from clicked points or landmarks; move, aim, select
``view``         poses, strain, colours
``state``        the edited layers (design, attachments, clutches, budget) with undo
``session``      save/load a session folder; open problem files, runs and sessions
``folders``      where the page may read: under the folders of the command line only
``runs``         run folders: compatibility, iterations, progress picture
``results``      a simulated design as the page keeps it; the results table
``settings``     the page's settings and the edit tools
``jobs``         background threads that report, stop and fail without losing edits
``page``         the Page protocol: what the controllers need from the page
``edit``         controller: tools on clicked garment points, clutch actions, undo
``simulations``  controller: designs A and B through the one design evaluator
``optimise``     controller: BESO through the one run driver; open and scrub runs
``scene``        what the garment looks like now; the viser meshes and picking
``panel``        the viser controls
``gate``         who may connect: the studio's own page with the session token
``app``          :class:`Studio`, the page (``kgarment studio``): the parts, files
===============  =====================================================================
"""

from kgarment.studio.app import Studio
from kgarment.studio.session import Opened, read_source

__all__ = ["Opened", "Studio", "read_source"]
