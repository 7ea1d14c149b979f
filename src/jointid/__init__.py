"""jointid: identification of nonlinear bolted-joint parameters by force-state mapping.

The data flow is the package layout: ``io`` (records, campaigns) -> ``signal`` (state
signals) -> ``modal`` (structure, modal coordinates) -> ``identify`` (force-state
mapping, laws) -> ``simulate`` (harmonic balance, time integration) -> ``rig`` (virtual
test rig) -> ``report`` (tables, figures, HTML); :mod:`jointid.workflow` runs a campaign
through it and :mod:`jointid.cli` is the command line.
"""

from __future__ import annotations

__version__ = "0.1.0"
