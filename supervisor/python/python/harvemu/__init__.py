"""The emulated 4MZ-6A cotton harvester's CAN network for Python, in virtual time or paced by the
wall clock.

``can.Bus(interface="harvemu", channel="harv0", without=["F5"], seed=2011)`` puts the program on
the emulated bus in the place of the nodes it leaves out (docs/PYTHON.md).
"""

from ._harvemu import Harvester
from .bus import HarvemuBus

__all__ = ["Harvester", "HarvemuBus"]
