"""dvrk_twin: kinematics of the da Vinci Research Kit (dVRK) manipulators.

Closed-loop kinematic trees of the PSM, ECM, setup joints, the patient-side cart and the MTMs,
computed by a Rust core (crate ``dvrk-kin``).

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
    DvrkError as DvrkError,
    IkError as IkError,
    InputError as InputError,
    Model as Model,
    ModelError as ModelError,
    ModelNotFoundError as ModelNotFoundError,
    __version__ as __version__,
    builtin_models as builtin_models,
)

__all__ = [
    "DvrkError",
    "IkError",
    "InputError",
    "Model",
    "ModelError",
    "ModelNotFoundError",
    "__version__",
    "builtin_models",
]
