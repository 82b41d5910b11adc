"""The simulator: batched vehicle models, the AD function, sensor models, the closed loop, the
resimulation of scenario descriptions, and seeded campaigns (serial or on Dask).

``experiments/`` (the cut-in, the T-junction, the SimpleCar sweep) are leaves: only ``paper``,
``cli`` and the simulator registry (:mod:`simcred.sim.registry`, what ``simcred simulate`` and
``validate`` run) import them (docs/architecture.md).
"""

from simcred.sim.campaign import Campaign, run_id
from simcred.sim.closed_loop import LoopRecord, run_closed_loop
from simcred.sim.driver import ADFunction, DriverConfig
from simcred.sim.resimulation import resimulate
from simcred.sim.sensors import (
    IdealSensor,
    OffsetDelaySensor,
    Sensor,
    TrackerSensor,
    estimate_sensor,
)
from simcred.sim.vehicles import (
    VEHICLE_MODELS,
    KinematicSingleTrack,
    SimpleCar,
    SingleTrack,
    VehicleModel,
    vehicle_model,
)

__all__ = [
    "VEHICLE_MODELS",
    "ADFunction",
    "Campaign",
    "DriverConfig",
    "IdealSensor",
    "KinematicSingleTrack",
    "LoopRecord",
    "OffsetDelaySensor",
    "Sensor",
    "SimpleCar",
    "SingleTrack",
    "TrackerSensor",
    "VehicleModel",
    "estimate_sensor",
    "resimulate",
    "run_closed_loop",
    "run_id",
    "vehicle_model",
]
