"""Simulation engines other than our own (``inertia_id.physics.simulate``).

Each engine turns a scenario, a candidate inertia and an actuation sequence into gyro
telemetry with software we did not write, so that the classifiers can be checked against
telemetry we did not generate ourselves. Engines are optional extras: importing this
package never imports the engine's own library; calling an engine does.

- :mod:`inertia_id.physics.engines.basilisk`: AVS Lab's Basilisk (``pip install
  "inertia-id[basilisk]"``), its spacecraft hub, external torque effector and IMU model.
"""

from __future__ import annotations

from .basilisk import (
    CANTED_SEQUENCE,
    BasiliskTelemetry,
    BasiliskUnavailableError,
    basilisk_available,
    basilisk_version,
    canted_full_tensor_scenario,
    simulate_basilisk,
)

__all__ = [
    "CANTED_SEQUENCE",
    "BasiliskTelemetry",
    "BasiliskUnavailableError",
    "basilisk_available",
    "basilisk_version",
    "canted_full_tensor_scenario",
    "simulate_basilisk",
]
