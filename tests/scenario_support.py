"""The inputs most tests start from: the paper's hand-designed sequence and the tensor of
its first candidate.

Tests import this module as ``scenario_support`` (``tests/`` is on ``sys.path``, see
``service_support``). Every suite used to spell these two out again; they are inputs, not
expectations, so one copy serves them all.
"""

from __future__ import annotations

import numpy as np

# The paper's "good" sequence: the three positive-axis thrusters at full duty, 4 steps.
GOOD_SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4

# Candidate 0 of the paper preset (its base inertia), kg m².
I0 = np.diag([100.0, 60.0, 90.0])
