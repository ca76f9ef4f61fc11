"""The bounds on a stated touch noise (mm), which every solver and the request schemas share.

A module of its own, free of numpy and scipy: the schemas read these bounds, and a process that
only reads schemas (`tcpcal publish`, the CLI's commands) need not import the solvers for them.
"""

from __future__ import annotations

#: Upper bound on a touch noise option, to catch unit mistakes (m for mm).
MAX_TOUCH_NOISE_MM = 100.0
#: Below this (mm) a noise figure is no measurement, and its square vanishes in the weights.
MIN_TOUCH_NOISE_MM = 1e-6
