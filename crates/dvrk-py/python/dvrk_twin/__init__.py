"""dvrk_twin: the da Vinci Research Kit (dVRK) manipulators as closed-loop mechanisms.

Closed-loop kinematic trees of the PSM, ECM, setup joints, the patient-side cart and the MTMs
(:class:`Model`, crate ``dvrk-kin``), headless dynamic simulation of the paper's scenes
(:class:`Sim`, :func:`run_scene`, crate ``dvrk-sim``; many copies stepped in parallel,
:class:`BatchSim`; :func:`export_mjcf` and
:mod:`dvrk_twin.mujoco_run` run the same scenes in MuJoCo) and motion-capture calibration
(:func:`pivot`, :func:`axis`, :func:`read_recording`, crate ``dvrk-calib``), computed by a Rust core.

Units: lengths in m, angles in rad. Poses are 4x4 homogeneous matrices (rotation, translation
in m) in the model's world frame. ``q`` holds one value per actuated joint (rad for revolute, m
for prismatic joints) in the order of ``Model.joint_names``.

>>> import dvrk_twin
>>> psm = dvrk_twin.Model.load("psm")
>>> psm.fk(psm.home, frame="tool_tip").shape
(4, 4)

Errors: every error is a :class:`DvrkError`; argument and file errors are also ``ValueError``
and a missing model is also a ``FileNotFoundError`` (see :class:`ModelNotFoundError`).
"""

from ._dvrk_twin import (
    BatchSim as BatchSim,
    DvrkError as DvrkError,
    IkError as IkError,
    InputError as InputError,
    Model as Model,
    Sim as Sim,
    ModelError as ModelError,
    ModelNotFoundError as ModelNotFoundError,
    __version__ as __version__,
    axis as axis,
    builtin_models as builtin_models,
    builtin_scenes as builtin_scenes,
    discrepancy as discrepancy,
    export_mjcf as export_mjcf,
    identify as identify,
    pivot as pivot,
    read_recording as read_recording,
    run_scene as run_scene,
    serve as serve,
    synth_hidden_effect as synth_hidden_effect,
)

__all__ = [
    "BatchSim",
    "DvrkError",
    "IkError",
    "InputError",
    "Model",
    "Sim",
    "ModelError",
    "ModelNotFoundError",
    "__version__",
    "axis",
    "builtin_models",
    "builtin_scenes",
    "discrepancy",
    "export_mjcf",
    "identify",
    "pivot",
    "read_recording",
    "run_scene",
    "serve",
    "synth_hidden_effect",
]
