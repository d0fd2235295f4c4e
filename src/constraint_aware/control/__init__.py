"""The executor and what it needs from a robot; none of these names imports MuJoCo.

The simulated run (`constraint_aware.control.simulate`) is imported from its module: it
brings in the simulator.
"""

from constraint_aware.control.calibrate import CalibrationConfig, calibrate
from constraint_aware.control.controllers import (
    CONTROLLERS,
    POLICY_CONTROLLERS,
    ControlInput,
    DirectionController,
    make_controller,
)
from constraint_aware.control.executor import Executor, command_jump_bound
from constraint_aware.control.executor_config import (
    ExecutorConfig,
    GoalConfig,
    GuardsConfig,
    LimitsConfig,
    RobotOverrides,
    SelfCheckConfig,
    TimingConfig,
    TorquePolicyConfig,
    max_grasp_play,
)
from constraint_aware.control.free_space import FreeSpaceConfig, calibrate_free_space
from constraint_aware.control.probe import (
    PROBE_VERDICTS,
    ProbeConfig,
    ProbeResult,
    probe_sensor,
    probed_settings,
)
from constraint_aware.control.profile import Measurement, ProfileFileError, RobotProfile
from constraint_aware.control.record import OUTCOME_MEANINGS, OUTCOMES, RunRecord, StepRecord
from constraint_aware.control.robot import Pose, Robot, TaskMonitor, Wrench, reported_stiffness
from constraint_aware.control.run_inputs import INPUT_NAMES, INPUT_SOURCES, MissingInputError
from constraint_aware.control.settings import Settings, parse_settings

__all__ = [
    "CONTROLLERS",
    "INPUT_NAMES",
    "INPUT_SOURCES",
    "OUTCOMES",
    "OUTCOME_MEANINGS",
    "POLICY_CONTROLLERS",
    "PROBE_VERDICTS",
    "CalibrationConfig",
    "ControlInput",
    "DirectionController",
    "Executor",
    "ExecutorConfig",
    "FreeSpaceConfig",
    "GoalConfig",
    "GuardsConfig",
    "LimitsConfig",
    "Measurement",
    "MissingInputError",
    "Pose",
    "ProbeConfig",
    "ProbeResult",
    "ProfileFileError",
    "Robot",
    "RobotOverrides",
    "RobotProfile",
    "RunRecord",
    "SelfCheckConfig",
    "Settings",
    "StepRecord",
    "TaskMonitor",
    "TimingConfig",
    "TorquePolicyConfig",
    "Wrench",
    "calibrate",
    "calibrate_free_space",
    "command_jump_bound",
    "make_controller",
    "max_grasp_play",
    "parse_settings",
    "probe_sensor",
    "probed_settings",
    "reported_stiffness",
]
