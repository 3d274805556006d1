"""People's bodies in a stepped ``MultibodyPlant``, moved where their block puts them."""

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
        self._nv = nv
        self._mass_matrix = np.array(
            [[b.default_mass(), b.default_mass(), b.default_rotational_inertia().get_moments()[2]]
             for b in bodies]).reshape(-1, 3)
        self._plant_state = self.DeclareVectorInputPort("plant_state", nq + nv)
        self._positions = self.DeclareVectorInputPort("positions",
                                                      PLANAR_POSITION_SIZE * self._m)
        self.DeclareVectorOutputPort("generalized_force", BasicVector(nv), self._calc_forces)

    def _calc_forces(self, context, output: BasicVector) -> None:
        x = self._plant_state.Eval(context)
        target = self._positions.Eval(context).reshape(self._m, PLANAR_POSITION_SIZE)
        error = target - x[self._q]
        error[:, 2] = -np.mod(-error[:, 2] + np.pi, 2.0 * np.pi) + np.pi
        forces = np.zeros(self._nv)
        forces[self._f] = self._mass_matrix * (error / self._h - x[self._v]) / self._h
        output.SetFromVector(forces)
