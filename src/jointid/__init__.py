"""jointid: identification of nonlinear bolted-joint parameters by force-state mapping."""

from __future__ import annotations

__version__ = "0.1.0"
