"""The demo stages of ``jmeshtex demo``, one module per method (also used by notebooks and tests)."""

from . import dgts as dgts
from . import fl as fl
from . import fldm as fldm
from . import meshmatch as meshmatch
from . import surfacecnn as surfacecnn
