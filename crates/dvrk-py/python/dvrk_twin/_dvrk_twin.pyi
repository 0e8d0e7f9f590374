"""Type stubs of the native module ``dvrk_twin._dvrk_twin`` (re-exported by ``dvrk_twin``).

Units: lengths in m, angles in rad. Poses are 4x4 homogeneous matrices.
"""

import os
from typing import Any, Dict, List, Optional, Tuple, Union, final

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "BatchSim",
    "DvrkError",
    "IkError",
    "InputError",
    "Model",
    "ModelError",
    "ModelNotFoundError",
    "__version__",
    "builtin_models",
]

__version__: str

_FrameArg = Union[int, str]
"""A frame: its number in the paper (int, see ``Model.frame_indices``) or its name (str)."""

class DvrkError(Exception):
    """Base class of every error raised by dvrk_twin. The message is the line the ``dvrk`` CLI prints."""

class ModelError(DvrkError, ValueError):
    """A model or tool file is invalid; the message names the file, the field and the value."""

class ModelNotFoundError(DvrkError, FileNotFoundError, ValueError):
    """``Model.load`` was given neither a built-in name nor an existing file (the message lists the
    valid names), or a tool file that does not exist."""

class InputError(DvrkError, ValueError):
    """An argument of the wrong size or shape, a non-finite value, or an unknown frame."""

class IkError(DvrkError, ValueError):
    """Inverse kinematics found no solution (out of reach, or only outside the joint limits)."""

def builtin_models() -> List[str]:
    """Names of the built-in models accepted by ``Model.load``."""

@final
class Model:
    """A kinematic model: a tree of frames driven by the actuated joints ``q`` (rad / m), with
    loop closures and a remote centre of motion (RCM). Immutable and thread-safe."""

    @staticmethod
    def load(
        name_or_path: Union[str, "os.PathLike[str]"],
        tool: Optional[Union[str, "os.PathLike[str]"]] = None,
    ) -> "Model":
        """Load a built-in model (``builtin_models()``) or a file: ``.toml`` model or system,
        dVRK arm ``.json``, ``.urdf``. ``tool``: a dVRK tool ``.json`` for a model with a tool
        (PSM). Raises ModelNotFoundError (also FileNotFoundError, ValueError) for an unknown name
        or missing file, ModelError (also ValueError) for an invalid file."""

    @property
    def name(self) -> str:
        """Model name."""
    @property
    def title(self) -> str:
        """One-line description."""
    @property
    def nq(self) -> int:
        """Number of actuated joints (length of ``q``)."""
    @property
    def nframes(self) -> int:
        """Number of frames."""
    @property
    def joint_names(self) -> List[str]:
        """Joint names in the order of ``q``."""
    @property
    def joint_types(self) -> List[str]:
        """``"revolute"`` (rad) or ``"prismatic"`` (m) per joint."""
    @property
    def joint_limits(self) -> NDArray[np.float64]:
        """Shape (nq, 2): lower, upper per joint (rad or m)."""
    @property
    def home(self) -> NDArray[np.float64]:
        """Home configuration, shape (nq,) (rad or m)."""
    @property
    def frame_names(self) -> List[str]:
        """Frame names in frame-position order (the order of ``fk`` results)."""
    @property
    def frame_indices(self) -> List[int]:
        """The paper's frame number of each frame position."""
    @property
    def frame_parents(self) -> List[Optional[int]]:
        """Parent frame position of each frame, None for a child of the base."""
    @property
    def tip(self) -> int:
        """Frame position of the tool tip (default frame of ``jacobian`` and ``ik``)."""
    @property
    def base(self) -> NDArray[np.float64]:
        """Pose of the model's base in the world, shape (4, 4) (m)."""
    @property
    def rcm(self) -> Optional[NDArray[np.float64]]:
        """RCM in the model's base frame, shape (3,) (m), or None."""
    @property
    def bodies(self) -> List[Tuple[str, List[int]]]:
        """Rigid bodies: (name, [frame positions])."""
    @property
    def closures(self) -> List[Tuple[str, int, NDArray[np.float64], int, NDArray[np.float64]]]:
        """Loop closures: (name, frame, point (3,) m, partner, partner_point (3,) m); frames are
        frame positions."""

    def frame_position(self, frame: _FrameArg) -> int:
        """Frame position of a frame given by paper number or name (InputError if unknown)."""

    def inverse_dynamics(self, q: ArrayLike, qd: Optional[ArrayLike] = None, qdd: Optional[ArrayLike] = None, effects: bool = True) -> NDArray[np.float64]:
        """Drive efforts (N·m, N) at q, qd, qdd ((nq,) or (N, nq); None: zero): rigid bodies with
        the file's [[inertials]] (else the built-in ones) and payloads, gravity (0, 0, -9.81)
        m/s^2, and with ``effects`` friction, springs and motor inertias."""

    def mass_matrix(self, q: ArrayLike, effects: bool = True) -> NDArray[np.float64]:
        """Joint-space inertia (nq, nq) or (N, nq, nq) (kg m^2, kg), motor inertias with ``effects``."""

    def gravity(self, q: ArrayLike) -> NDArray[np.float64]:
        """Gravity torque g(q) (N·m, N), (nq,) or (N, nq)."""

    def regressor(self, q: ArrayLike, qd: Optional[ArrayLike] = None, qdd: Optional[ArrayLike] = None) -> NDArray[np.float64]:
        """Inertial-parameter regressor (nq, 10 nbodies) or (N, ...): ``Y @ inertial_parameters()``
        is the rigid bodies' inverse dynamics."""

    def inertial_parameters(self) -> NDArray[np.float64]:
        """Per body (m, m cx, m cy, m cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz) about its first frame's
        origin (kg, kg m, kg m^2), payloads applied: the regressor's columns."""

    def fk(self, q: ArrayLike, frame: Optional[_FrameArg] = None) -> NDArray[np.float64]:
        """World poses (4x4, m) at q (rad / m). q (nq,) -> (nframes, 4, 4), or (4, 4) with
        ``frame``; q (N, nq) -> (N, nframes, 4, 4) or (N, 4, 4), computed without the GIL.
        Size and finiteness of q are checked (InputError), joint limits are not."""

    def jacobian(self, q: ArrayLike, frame: Optional[_FrameArg] = None) -> NDArray[np.float64]:
        """Geometric Jacobian of ``frame`` (default: tip) at q: (6, nq), rows 0-2 linear velocity
        (m/s per rad/s or m/s), rows 3-5 angular velocity (rad/s), world axes. q (N, nq) ->
        (N, 6, nq)."""

    def ik(
        self,
        pose: ArrayLike,
        seed: Optional[ArrayLike] = None,
        frame: Optional[_FrameArg] = None,
    ) -> NDArray[np.float64]:
        """Joint positions (nq,) (rad / m) within the limits that put ``frame`` (default: tip)
        at ``pose`` (4x4, world, m). Full pose for arms with >= 6 joints moving the frame
        (1e-9 m / 1e-9 rad), position only otherwise (ECM). Raises IkError."""

    def closure_residual(self, q: ArrayLike) -> float:
        """Largest loop-closure gap at q (m); 0.0 without closures."""

    def pivot_residual(self, q: ArrayLike) -> Optional[float]:
        """Distance from the RCM to the insertion axis at q (m); None without an RCM."""

    def check(self, samples: int = 2000) -> Dict[str, Any]:
        """Figures of ``dvrk model check`` over ``samples`` configurations (m, rad), with
        ``ok`` (bool) and ``problems`` (list[str])."""

_JointArg = Union[int, str]

@final
class BatchSim:
    """Many independent copies of a scene stepped together on a thread pool, the GIL released
    while they step (reduced engine by default). The arrays are (n, nq) float64 numpy arrays
    this object owns: ``step`` reads ``target``, ``target_velocity``, ``effort_command`` and
    writes ``q``, ``qd``, ``effort`` in place. Units: m, rad, s, N, N·m."""

    @staticmethod
    def from_scene(scene: str, n: int, engine: str = "reduced", threads: int = 0) -> "BatchSim":
        """``n`` copies of a built-in scene or scene file at its start, holding it, stepped on
        ``threads`` threads (0: one per core)."""
    @property
    def n(self) -> int: ...
    @property
    def nq(self) -> int: ...
    @property
    def dt(self) -> float:
        """Time step (s)."""
    @property
    def threads(self) -> int: ...
    @property
    def joint_names(self) -> List[str]:
        """Joint names ``ARM/joint``, the arrays' columns."""
    @property
    def joint_limits(self) -> NDArray[np.float64]:
        """Joint limits (nq, 2) (rad, m)."""
    @property
    def effort_limits(self) -> List[float]:
        """Drive effort limits (N·m, N), where effort commands are clamped."""
    @property
    def time(self) -> List[float]:
        """Each copy's simulated time (s)."""
    @property
    def q(self) -> NDArray[np.float64]:
        """Measured joint positions (n, nq) (rad, m), updated in place by ``step``."""
    @property
    def qd(self) -> NDArray[np.float64]:
        """Measured joint velocities (n, nq) (rad/s, m/s)."""
    @property
    def effort(self) -> NDArray[np.float64]:
        """Efforts applied at the last step (n, nq) (N·m, N)."""
    @property
    def target(self) -> NDArray[np.float64]:
        """Position targets (n, nq) (rad, m), read by ``step``; assignable (broadcast)."""
    @target.setter
    def target(self, value: ArrayLike) -> None: ...
    @property
    def target_velocity(self) -> NDArray[np.float64]:
        """Velocity feed-forward (n, nq) (rad/s, m/s)."""
    @target_velocity.setter
    def target_velocity(self, value: ArrayLike) -> None: ...
    @property
    def effort_command(self) -> NDArray[np.float64]:
        """Efforts (n, nq) (N·m, N) of joints in effort mode."""
    @effort_command.setter
    def effort_command(self, value: ArrayLike) -> None: ...
    def step(self, k: int = 1) -> None:
        """Advance every copy ``k`` steps with the command arrays, in parallel, without the GIL."""
    def reset(self, copies: Union[int, List[int], None] = None, q: Optional[ArrayLike] = None) -> None:
        """Rebuild copies (None: all) at ``q`` ((nq,) or (len(copies), nq); None: the scene's
        start), holding it."""
    def set_model(self, copy: int, path: Union[str, os.PathLike], arm: int = 0) -> None:
        """Give one copy's arm a model file (payloads, friction, an identified model) and
        rebuild it at its start."""
    def set_gains(self, copy: int, joint: _JointArg, kp: float, ki: float, kd: float) -> None:
        """PID gains of one copy's joint."""
    def set_mode(self, joint: _JointArg, mode: str, copy: Optional[int] = None) -> None:
        """"pid", "position" or "effort" for one copy's joint (None: every copy's)."""
    def frame_poses(self, frame: Union[str, int, None] = None, arm: int = 0) -> NDArray[np.float64]:
        """World poses (n, 4, 4) (m) of a frame (None: ``tool_tip``) of arm ``arm`` in every copy."""

class Sim:
    """A running dynamic simulation of a scene (rapier or the reduced engine, f64). Units: m,
    rad, s, N, N·m."""

    @staticmethod
    def from_scene(scene: str, loops: str = "impulse", solver_iterations: Optional[int] = None, engine: Optional[str] = None) -> "Sim":
        """Build a built-in scene ("psm", "ecm", ...) or a scene file. ``loops``: "impulse"
        (loop-closing impulse joints) or "coupling" (loop-free). ``engine``: "rapier" or
        "reduced" (forward dynamics in the actuated joints, loops exact, no contacts);
        the scene's when None."""
    @property
    def joint_names(self) -> List[str]:
        """Joint names ``ARM/joint`` in the order of ``q``."""
    @property
    def nq(self) -> int: ...
    @property
    def time(self) -> float:
        """Simulated time (s)."""
    @property
    def dt(self) -> float:
        """Time step (s)."""
    @property
    def q(self) -> NDArray[np.float64]:
        """Measured joint positions (nq,) (rad, m)."""
    @property
    def qd(self) -> NDArray[np.float64]:
        """Measured joint velocities (nq,) (rad/s, m/s)."""
    @property
    def closure_error(self) -> float:
        """Largest loop-closure gap now (m)."""
    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps of ``dt``."""
    def set_mode(self, joint: _JointArg, mode: str) -> None:
        """"pid", "position" or "effort"."""
    def set_target(self, joint: _JointArg, position: float, velocity: float = 0.0) -> None:
        """Position target (rad, m) and velocity feed-forward (rad/s, m/s)."""
    def set_effort(self, joint: _JointArg, effort: float) -> None:
        """Open-loop effort (N·m, N), clamped at the joint's effort limit."""
    def set_gains(self, joint: _JointArg, kp: float, ki: float, kd: float) -> None:
        """PID gains (N·m/rad or N/m, per s, times s)."""
    def effort(self, joint: _JointArg) -> float:
        """Effort applied at the last step (N·m, N)."""
    def serve(self, host: str = "127.0.0.1", port: int = 8765, rate: float = 100.0) -> str:
        """Serve the simulation live over the Foxglove WebSocket protocol (the topics of
        ``dvrk sim --out``), sampled every ``1 / rate`` s of simulated time as ``step`` advances
        it; ``port`` 0 picks a free one. Returns ``ws://HOST:PORT``."""
    def stop_serving(self) -> None:
        """Stop the live view (closes the connections)."""
    @property
    def live_url(self) -> Optional[str]:
        """The live view's address, or None."""

def serve(
    scene: str = "psm",
    domain: Optional[int] = None,
    rate: float = 200.0,
    duration: Optional[float] = None,
    engine: str = "reduced",
    out: Optional[Union[str, os.PathLike]] = None,
    networks: List[str] = ...,
    gravity_compensation: bool = False,
) -> Dict[str, Any]:
    """Serve a scene as a live ROS 2 twin in real time (`dvrk serve`); blocks for `duration`
    simulated seconds or until Ctrl-C; returns the summary."""
    ...

def run_scene(
    scene: str,
    duration: float,
    trajectory: str = "sine",
    loops: str = "impulse",
    solver_iterations: Optional[int] = None,
    engine: Optional[str] = None,
) -> Dict[str, Any]:
    """Run a scene for ``duration`` s ("sine": the paper's tracking test, or "hold") without the
    GIL; the summary of ``dvrk sim --json`` as a dict (real_time_factor, joints, max_closure_error
    (m), max_rcm_error (m), ...)."""

def builtin_scenes() -> List[str]: ...

def export_mjcf(name_or_path: str) -> str:
    """MJCF (MuJoCo XML) of a scene (built-in name or scene file) or of a model with its built-in
    inertials and gains, as ``dvrk export mjcf`` writes it (m, rad, s, kg, N, N·m)."""

def pivot(poses: ArrayLike, method: str = "one-step") -> Dict[str, Any]:
    """Pivot calibration (paper eq. 3-5) of marker poses (N, 4, 4) in the tracker frame (m):
    tip, pivot, rms_per_axis, rms, tip_std, pivot_std (m), samples, method, warnings."""

def axis(reference: ArrayLike, moving: ArrayLike, method: str = "sara") -> Dict[str, Any]:
    """Axis of rotation of ``moving`` about ``reference`` (poses (N, 4, 4), m): point (m, in the
    reference cluster's frame), direction, point_std (m), direction_std (rad), rms, samples."""

def read_recording(path: Union[str, "os.PathLike[str]"], topics: Optional[List[str]] = None) -> Dict[str, Any]:
    """Read an MCAP / Motive CSV / plain CSV recording: {"bodies": {name: {"t", "poses",
    "frame_id"}}, "joints": None or {"names", "t", "q"}, "warnings"} (s, m, rad)."""

def identify(
    recording: Union[str, "os.PathLike[str]"],
    model: str = "psm",
    format: str = "auto",
    validate: Optional[Union[str, "os.PathLike[str]"]] = None,
    arm: str = "PSM1",
    ablation: bool = True,
) -> Dict[str, Any]:
    """Dynamic identification (``dvrk identify``): inertial parameters (physically consistent),
    friction, offsets, motor inertia and springs; the JSON summary as a dict (relative torque
    errors per channel, rigid-body-only baseline, ``validation`` on ``validate``, ``ablation``
    unless ``ablation=False`` (most of the time: 12 of 14 s on the WPI PSM), effects and bodies with
    standard deviations, ``warnings``). SI units."""

def discrepancy(
    recording: Union[str, "os.PathLike[str]"],
    model: str = "psm",
    arm: str = "PSM1",
    tracking: bool = True,
    format: str = "mcap",
    max_rounds: int = 4,
    plot: Optional[Union[str, "os.PathLike[str]"]] = None,
    marker_topic: Optional[str] = None,
    marker_link: Optional[str] = None,
) -> Dict[str, Any]:
    """The discrepancy workflow (``dvrk discrepancy``) on a recording: ``format`` "mcap"
    (``/<arm>/setpoint_js`` and ``/<arm>/measured_js`` with efforts), "wpi-csv" or "csv"
    (``time``, ``q1..qN``, ``tau1..tauN``, optional ``setpoint1..setpointN``): which physical
    effect the model lacks, named and added to the model up to ``max_rounds`` times; the report as
    a dict (``verdict`` named/none/ambiguous, ``effects`` with parameters, 95% intervals, delta BIC
    and p-values, ``candidates``, RMS before/after, ``noise_floor``, ``steps``). ``plot`` (.png or
    .svg): the residual before and after against time, velocity, load and position.
    ``marker_topic`` (an MCAP pose topic, or a CSV's pose-column name) and ``marker_link`` (frame
    name or the paper's number): a tracked marker on that link adds the kinematic channel (report
    key ``kinematic``)."""

def synth_hidden_effect(
    path: Union[str, "os.PathLike[str]"],
    effect: str = "random",
    seed: int = 1,
    scene: str = "psm",
    duration: float = 30.0,
    marker_link: Optional[str] = None,
    engine: str = "rapier",
) -> Dict[str, Any]:
    """``dvrk synth hidden-effect``: write a recording (plain CSV for a .csv path, else MCAP with
    ``/<arm>/setpoint_js``, ``/<arm>/measured_js`` with efforts) simulated with hidden effects
    (a vocabulary name, two joined by ``+``, ``none``, ``random`` or ``random-pair``); with
    ``marker_link`` a tracker on that link too. Returns the answer (``effects`` with
    parameters and effect-to-noise ratios, ``marker_topic``). ``engine``: the truth's, ``rapier``
    (shares no dynamics code with the analysis) or ``reduced`` (about 16x faster)."""
