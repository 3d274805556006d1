"""The physics backend's wiring: a stepped plant in the loop with the robots block.

With a robots block that steps the plant (kind ``physics``), ``world.build_world`` makes the
plant discrete and adds it to the diagram; ``add_plant_stepping`` then closes the loop
(instead of ``world.add_plant_posing``): the plant's state goes to the robots block, whose
drive forces, plus those that move the people's bodies onto the humans block's positions
(``HumanBodyDriver``), go to the plant's applied generalized force input; a
``ContactRecorder`` notes the plant's contacts for the run summary (``physics_contacts``).

A building run across levels moves a lift's riders to the other level at the ride's end
(``payloads.Relocations``). The plant owns its bodies' state and is the only system that
may change it, so the plant itself applies them: ``add_plant_stepping`` gives it an input
``relocations`` (the robots block's ``relocate``: the moves not applied yet) and a
periodic unrestricted update at its time step, Drake's own event declared on the plant,
that puts each moved robot's planar joint on its pose at rest before that instant's step
(the robots block notes the moves applied at the same instants). In a run without lifts
(a robots block whose ``relocates`` is False) the plant has neither.
"""

from pydrake.common.value import Value
from pydrake.systems.framework import EventStatus
from pydrake.systems.primitives import Adder

from mrta_drake.humans.human_body_driver import HumanBodyDriver
from mrta_drake.payloads import Relocations
from mrta_drake.stack.contact_recorder import ContactRecorder
from mrta_drake.world.plant import World


def add_plant_stepping(builder, world: World, robots, human_positions=None) -> ContactRecorder:
    """Connect the stepped ``world.plant`` to ``robots`` (input ``plant_state``, output
    ``generalized_force``, and ``relocate`` when it ``relocates``) and, when there are people, to
    their ``plant_positions`` output port ``human_positions``; return the contact recorder
    added."""
    plant = world.plant
    state = plant.get_state_output_port()
    builder.Connect(state, robots.GetInputPort("plant_state"))
    if getattr(robots, "relocates", False):
        builder.Connect(robots.GetOutputPort("relocate"), _declare_relocation(plant, robots))
    forces = robots.GetOutputPort("generalized_force")
    if human_positions is not None and world.humans:
        driver = builder.AddNamedSystem("human_bodies", HumanBodyDriver(plant, world.humans))
        builder.Connect(state, driver.GetInputPort("plant_state"))
        builder.Connect(human_positions, driver.GetInputPort("positions"))
        adder = builder.AddNamedSystem("generalized_forces", Adder(2, plant.num_velocities()))
        builder.Connect(forces, adder.get_input_port(0))
        builder.Connect(driver.GetOutputPort("generalized_force"), adder.get_input_port(1))
        forces = adder.get_output_port()
    builder.Connect(forces, plant.get_applied_generalized_force_input_port())
    contacts = builder.AddNamedSystem("contacts", ContactRecorder(
        plant, world.scene_graph, world.robots, world.humans))
    builder.Connect(plant.get_contact_results_output_port(),
                    contacts.GetInputPort("contact_results"))
    return contacts


def _declare_relocation(plant, robots):
    """Declare on ``plant`` (discrete, finalized) the input ``relocations`` and the periodic
    unrestricted update at its time step that applies them with ``robots.relocated``;
    return the input port."""
    port = plant.DeclareAbstractInputPort("relocations", Value[object](Relocations()))

    def relocate(context, state) -> EventStatus:
        moves = port.Eval(context).moves
        if not any(moves):
            return EventStatus.DidNothing()
        vector = state.get_mutable_discrete_state().get_mutable_vector(0)
        vector.SetFromVector(robots.relocated(vector.value(), moves))
        return EventStatus.Succeeded()

    plant.DeclarePeriodicUnrestrictedUpdateEvent(plant.time_step(), 0.0, relocate)
    return port
