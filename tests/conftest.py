"""Hypothesis profiles: random exploration on a workstation, the same examples every run in CI.

``HYPOTHESIS_PROFILE=ci`` (set by ``.ci/run``) selects the ``ci`` profile; without it the
property tests run with Hypothesis' defaults, drawing new examples on every run and replaying
the failures it stored in ``.hypothesis/``.

The ``ci`` profile makes a run a function of the code alone, so a result can be reproduced
from the commit:

- ``derandomize``: the examples are seeded by a hash of each test, the same on every run;
- ``database=None``: no examples replayed from, or written to, a local database;
- ``deadline=None`` and no ``too_slow`` health check: both measure wall time, which on a shared
  CI machine depends on its load, not on the code. The health checks that do not time anything
  (filtering too much, data too large) stay on.

A test's own ``@settings`` (its number of examples, say) still applies on top of the profile.
"""

import os

from hypothesis import HealthCheck, settings

settings.register_profile("ci", derandomize=True, database=None, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))
