"""Recording the contacts of a stepped ``MultibodyPlant``: the physics backend's collisions."""

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import Value
from pydrake.geometry import Role, SceneGraph
from pydrake.multibody.plant import ContactResults, MultibodyPlant
from pydrake.systems.framework import LeafSystem

ROBOT, HUMAN, OBSTACLE = "robot", "human", "obstacle"
_KIND_ORDER = (ROBOT, HUMAN, OBSTACLE)  # a pair's kind names its bodies' kinds in this order
CONTACT_GAP = 0.1  # s; a contact that resumes within this after it ended is the same one


@dataclass
class _Pair:
    """What was seen of one pair of contacting bodies so far (SI units)."""

    first_time: float
    last_time: float = float("-inf")  # s, the last sample in contact
    count: int = 0  # contact onsets
    duration: float = 0.0  # s in contact
    impulse: float = 0.0  # N s, integral of the contact force's magnitude
    max_force: float = 0.0  # N
    max_penetration: float = 0.0  # m


class ContactRecorder(LeafSystem):
    """Notes the plant's point contacts after every plant step (publish events only: it
    never changes the run): the pairs in contact in the state the step reached and their
    penetration, with the contact forces of the plant's next step from that state (the
    plant's output ports are not sampled, ``world.plant.PlantPhysics``; the blocks whose
    outputs drive the plant, the controller and the people, update at the next step's
    instant together with the plant, so that step uses the inputs read here).

    .. pydrake_system::

        name: ContactRecorder
        input_ports:
        - contact_results

    A body is named by its model instance (a robot's or person's name); the building's
    geometry, all on the world body, by the geometry's name (e.g. ``wall_12``). For every
    pair of bodies that touched: how many times contact began, when first, for how long,
    the integral of the contact force's magnitude (impulse, N s), the largest force (N)
    and the deepest penetration (m); ``summary()`` reports them. A contact that resumes
    within ``CONTACT_GAP`` s of its end (a robot scraping along a wall makes and breaks
    contact every few steps) is the same contact.

    Input ``contact_results``: the plant's ``ContactResults``.
    """

    def __init__(self, plant: MultibodyPlant, scene_graph: SceneGraph, robot_models=(),
                 human_models=()):
        super().__init__()
        self._period = plant.time_step()
        if not self._period > 0:
            raise ValueError("the plant must be discrete (time_step > 0)")
        inspector = scene_graph.model_inspector()
        kinds = {m: ROBOT for m in robot_models} | {m: HUMAN for m in human_models}
        self._names: dict = {}
        for geometry in inspector.GetAllGeometryIds(Role.kProximity):
            body = plant.GetBodyFromFrameId(inspector.GetFrameId(geometry))
            if body.index() == plant.world_body().index():
                self._names[geometry] = (inspector.GetName(geometry), OBSTACLE)
            else:
                model = body.model_instance()
                self._names[geometry] = (plant.GetModelInstanceName(model),
                                         kinds.get(model, OBSTACLE))
        self._pairs: dict[tuple[str, str], _Pair] = {}
        self._kinds: dict[tuple[str, str], str] = {}
        self.DeclareAbstractInputPort("contact_results", Value(ContactResults()))
        self.DeclarePeriodicPublishEvent(self._period, 0.0, self._sample)

    def _sample(self, context) -> None:
        results = self.get_input_port().Eval(context)
        now = context.get_time()
        seen: dict[tuple[str, str], list[float]] = {}
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)
            pair = info.point_pair()
            (a, kind_a), (b, kind_b) = sorted([self._names[pair.id_A], self._names[pair.id_B]])
            key = (a, b)
            self._kinds[key] = "_".join(sorted([kind_a, kind_b], key=_KIND_ORDER.index))
            force, depth = seen.setdefault(key, [0.0, 0.0])
            seen[key] = [force + float(np.linalg.norm(info.contact_force())),
                         max(depth, float(pair.depth))]
        for key, (force, depth) in seen.items():
            record = self._pairs.setdefault(key, _Pair(first_time=now))
            if now - record.last_time > CONTACT_GAP + 0.5 * self._period:
                record.count += 1
            record.last_time = now
            record.duration += self._period
            record.impulse += force * self._period
            record.max_force = max(record.max_force, force)
            record.max_penetration = max(record.max_penetration, depth)

    def summary(self) -> dict:
        """The ``physics_contacts`` section of a run's summary: ``time_step`` (s),
        ``count`` (contact onsets over all pairs), ``count_by_kind`` (``robot_robot``,
        ``robot_human``, ``robot_obstacle``), ``max_penetration`` (m) and ``pairs``, one
        entry per pair of bodies that touched (``between``, ``kind``, ``count``,
        ``first_time``, ``duration``, ``impulse``, ``max_force``, ``max_penetration``),
        in order of first contact."""
        pairs = sorted(self._pairs.items(), key=lambda item: (item[1].first_time, item[0]))
        by_kind = {f"{ROBOT}_{other}": 0 for other in (ROBOT, HUMAN, OBSTACLE)}
        for key, record in pairs:
            by_kind[self._kinds[key]] = by_kind.get(self._kinds[key], 0) + record.count
        return {
            "time_step": self._period,
            "count": sum(record.count for _, record in pairs),
            "count_by_kind": by_kind,
            "max_penetration": max((r.max_penetration for _, r in pairs), default=0.0),
            "pairs": [{"between": list(key), "kind": self._kinds[key], "count": r.count,
                       "first_time": r.first_time, "duration": r.duration,
                       "impulse": r.impulse, "max_force": r.max_force,
                       "max_penetration": r.max_penetration} for key, r in pairs],
        }
