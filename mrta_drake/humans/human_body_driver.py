"""People's bodies in a stepped ``MultibodyPlant``, moved where their block puts them."""

import numba
import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, LeafSystem

from mrta_drake.payloads import PLANAR_POSITION_SIZE


class HumanBodyDriver(LeafSystem):
    """Moves M people's planar bodies in a discrete plant onto given positions, mocap-style.

    .. pydrake_system::

        name: HumanBodyDriver
        input_ports:
        - plant_state
        - positions
        output_ports:
        - generalized_force

    Each step the generalized force on a person's planar joint is the one that, without
    contact, brings the body exactly to its target in that step: with step h, mass matrix
    diag(m, m, I_zz), position q and velocity v at the step's start, f = M ((q* - q) / h - v)
    / h (a PD with deadbeat gains m / h^2 and m / h; the heading error wrapped to (-pi, pi]).
    People are thus kinematic: a robot in the way is pushed aside with whatever force it
    takes, and a person deflected by a contact is back on target the next step. A jump of the
    target (a person entering from its parking spot) is made in one step.

    Input ``plant_state``: the plant's state [q; v].
    Input ``positions`` (3M): targets [x, y, theta] per person (world frame, m, rad), the
        humans block's ``plant_positions``.
    Output ``generalized_force`` (the plant's nv): [f_x, f_y, tau_z] on each person's
        planar joint (world frame, N, N m), zero for the plant's other joints.
    """

    def __init__(self, plant: MultibodyPlant, human_models):
        super().__init__()
        self._m = len(human_models)
        self._h = plant.time_step()
        if not self._h > 0:
            raise ValueError("the plant must be discrete (time_step > 0)")
        nq, nv = plant.num_positions(), plant.num_velocities()
        joints = [plant.get_joint(plant.GetJointIndices(m)[0]) for m in human_models]
        bodies = [plant.GetBodyByName("base", m) for m in human_models]
        offsets = np.arange(3)
        self._q = np.array([j.position_start() + offsets for j in joints]).reshape(-1, 3)
        self._v = np.array([nq + j.velocity_start() + offsets for j in joints]).reshape(-1, 3)
        self._f = self._v - nq
        self._mass_matrix = np.array(
            [[b.default_mass(), b.default_mass(), b.default_rotational_inertia().get_moments()[2]]
             for b in bodies]).reshape(-1, 3)
        self._plant_state = self.DeclareVectorInputPort("plant_state", nq + nv)
        self._positions = self.DeclareVectorInputPort("positions",
                                                      PLANAR_POSITION_SIZE * self._m)
        self.DeclareVectorOutputPort("generalized_force", BasicVector(nv), self._calc_forces)

    def _calc_forces(self, context, output: BasicVector) -> None:
        _deadbeat_forces(self._plant_state.Eval(context), self._positions.Eval(context),
                         self._q, self._v, self._f, self._mass_matrix, self._h,
                         output.get_mutable_value())


@numba.njit(cache=True)
def _deadbeat_forces(x, targets, q, v, f, mass_matrix, h, forces):
    """``HumanBodyDriver``'s forces into ``forces`` (the plant's nv): from the plant state
    ``x`` [q; v], the targets (3M) [x, y, theta] per person, the people's indices ``q``,
    ``v`` (M, 3) in ``x`` and ``f`` (M, 3) in ``forces``, their ``mass_matrix`` diagonals
    (M, 3) (kg, kg, kg m^2) and the step ``h`` (s); every other entry of ``forces`` zero."""
    forces[:] = 0.0
    for i in range(len(q)):
        for k in range(3):
            error = targets[3 * i + k] - x[q[i, k]]
            if k == 2:  # the heading error, wrapped to (-pi, pi]
                error = -np.mod(-error + np.pi, 2.0 * np.pi) + np.pi
            forces[f[i, k]] = mass_matrix[i, k] * (error / h - x[v[i, k]]) / h
