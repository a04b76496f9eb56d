"""Next-best-view planning made of parts: generators propose views, a utility scores them in one
C++ call, a selection picks one, terminations decide when to stop (planner.py). The parts are
registered by name (registry.py); scenarios (nbvkit.scenarios) compose them."""
from .parts import Choice, Proposal, Step
from .planner import Planner
from .registry import GENERATORS, TERMINATIONS
from .utilities import PythonUtility

__all__ = ["Planner", "Proposal", "Choice", "Step", "GENERATORS", "TERMINATIONS", "PythonUtility"]
