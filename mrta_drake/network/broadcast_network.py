"""Robots broadcasting their states, and leaders' commands to followers, over a lossy network
with latency and jitter."""

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import Value
from pydrake.systems.framework import BasicVector, LeafSystem

from mrta_drake.payloads import (
    ROBOT_STATE_SIZE,
    CommandMessages,
    NetworkViews,
    frozen_array,
)
from mrta_drake.scenario.schema import CommunicationConfig

_DUE = 1e-9  # s: a message due within this of a tick is delivered at it


@dataclass(frozen=True)
class Messages:
    """Messages in flight: message k goes to robot ``receiver[k]`` from ``sender[k]``, was
    sent at ``sent[k]`` and arrives at ``arrive[k]`` (s), carrying ``body[k]``."""

    arrive: np.ndarray
    receiver: np.ndarray
    sender: np.ndarray
    sent: np.ndarray
    body: np.ndarray

    @classmethod
    def none(cls, width: int) -> "Messages":
        return cls(np.zeros(0), np.zeros(0, int), np.zeros(0, int), np.zeros(0),
                   np.zeros((0, width)))

    def __add__(self, other: "Messages") -> "Messages":
        return Messages(*(np.concatenate([a, b]) for a, b in zip(
            (self.arrive, self.receiver, self.sender, self.sent, self.body),
            (other.arrive, other.receiver, other.sender, other.sent, other.body),
            strict=True)))

    def split(self, time: float) -> tuple["Messages", "Messages"]:
        """The messages due by ``time`` (oldest sent first), and the rest."""
        due = self.arrive <= time + _DUE
        order = np.argsort(self.sent[due], kind="stable")
        parts = [(a[due][order], a[~due]) for a in
                 (self.arrive, self.receiver, self.sender, self.sent, self.body)]
        return Messages(*(p[0] for p in parts)), Messages(*(p[1] for p in parts))


@dataclass(frozen=True)
class NetworkState:
    """The block's abstract state: what has been delivered, what is in flight, and the time
    of the last commands taken for sending (s)."""

    views: NetworkViews
    states_in_flight: Messages
    commands_in_flight: Messages
    last_commands: float


class BroadcastNetwork(LeafSystem):
    """Every robot broadcasts its state to every other robot at ``rate_hz``; cluster leaders'
    commands go to their followers as the controller sends them. Each message is lost with
    probability ``config.loss`` or arrives ``config.latency`` s plus a delay uniform in
    [0, ``config.jitter``] s after it was sent; a message older than one already received
    on the same link is dropped (out of order).

    .. pydrake_system::

        name: BroadcastNetwork
        input_ports:
        - robot_state
        - leader_commands (optional)
        output_ports:
        - views

    Input ``robot_state`` (4N): ``[x, y, theta, v]`` per robot in ``robot_names`` order,
    world frame, m, rad, m/s. Input ``leader_commands`` (``CommandMessages``): the
    controller's commands to followers; each new set (a later ``time``) is sent once.
    Output ``views`` (``NetworkViews``): what each robot has received, from the state; a
    command is stale after ``latency + jitter + stale_after`` s (its ``max_age``).

    One unrestricted update every 1 / ``rate_hz`` s sends the broadcasts and the new
    commands and delivers every message due by then, so delivery times are rounded up to
    the next tick. Before its first message from a robot, a robot knows it at its start
    (``start_states`` (N, 4), sent at 0 s). Losses and delays are drawn from a numpy
    Generator seeded by (``seed``, tick number): the same scenario and seed give the same
    messages.
    """

    def __init__(self, robot_names, start_states, config: CommunicationConfig, seed: int, *,
                 rate_hz: float):
        super().__init__()
        self._n = n = len(robot_names)
        self._config, self._seed, self._rate = config, int(seed), float(rate_hz)
        self._max_age = config.latency + config.jitter + config.stale_after
        starts = np.asarray(start_states, dtype=float).reshape(n, ROBOT_STATE_SIZE)
        receiver, sender = np.nonzero(~np.eye(n, dtype=bool))
        self._links = (receiver, sender)  # every ordered pair, receiver first
        self._robot_state = self.DeclareVectorInputPort(
            "robot_state", BasicVector(ROBOT_STATE_SIZE * n))
        self._commands = self.DeclareAbstractInputPort(
            "leader_commands", Value[object](CommandMessages()))
        initial = NetworkState(
            _views(0.0, np.broadcast_to(starts, (n, n, ROBOT_STATE_SIZE)), np.zeros((n, n)),
                   np.zeros((n, 2)), (-1,) * n, np.full(n, -np.inf), self._max_age),
            Messages.none(ROBOT_STATE_SIZE), Messages.none(2), -np.inf)
        self._state = self.DeclareAbstractState(Value[object](initial))
        self.DeclareAbstractOutputPort(
            "views", lambda: Value[object](initial.views),
            lambda context, output: output.set_value(
                context.get_abstract_state(self._state).get_value().views),
            prerequisites_of_calc={self.abstract_state_ticket(self._state)})
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / self._rate, 0.0, self._update)

    def _update(self, context, state) -> None:
        time = context.get_time()
        old: NetworkState = context.get_abstract_state(self._state).get_value()
        rng = np.random.default_rng([self._seed, round(time * self._rate)])
        states = self._robot_state.Eval(context).reshape(self._n, ROBOT_STATE_SIZE)
        receiver, sender = self._links
        in_flight = old.states_in_flight + self._send(rng, time, receiver, sender,
                                                      states[sender])
        due_states, states_left = in_flight.split(time)
        commands_in_flight, last_commands = old.commands_in_flight, old.last_commands
        sent = (self._commands.Eval(context) if self._commands.HasValue(context)
                else CommandMessages())
        if sent.time > last_commands:
            leaders = np.asarray(sent.leaders, dtype=int)
            followers = np.flatnonzero(leaders >= 0)
            commands_in_flight = commands_in_flight + self._send(
                rng, sent.time, followers, leaders[followers], sent.inputs[followers])
            last_commands = sent.time
        due_commands, commands_left = commands_in_flight.split(time)
        views = _delivered(old.views, time, states, due_states, due_commands)
        state.get_mutable_abstract_state(self._state).set_value(
            NetworkState(views, states_left, commands_left, last_commands))

    def _send(self, rng, time: float, receiver, sender, body) -> Messages:
        """The messages ``body`` from ``sender`` to ``receiver`` sent at ``time`` that are not
        lost, with their arrival times."""
        c = self._config
        kept = rng.random(len(receiver)) >= c.loss
        delay = c.latency + c.jitter * rng.random(len(receiver))
        return Messages(time + delay[kept], receiver[kept], sender[kept],
                        np.full(kept.sum(), time), np.asarray(body, dtype=float)[kept])


def _delivered(views: NetworkViews, time: float, own_states, states: Messages,
               commands: Messages) -> NetworkViews:
    """``views`` at ``time`` after each robot's own broadcast of ``own_states`` (N, 4) and the
    delivery of the due ``states`` and ``commands`` (oldest sent first)."""
    received, sent_at = np.array(views.states), np.array(views.sent_at)
    n = len(sent_at)
    received[np.arange(n), np.arange(n)] = own_states
    sent_at[np.arange(n), np.arange(n)] = time
    newer = _newest(states.receiver * n + states.sender) & (
        states.sent > sent_at[states.receiver, states.sender])
    received[states.receiver[newer], states.sender[newer]] = states.body[newer]
    sent_at[states.receiver[newer], states.sender[newer]] = states.sent[newer]
    inputs, sources = np.array(views.commands), np.array(views.command_from)
    command_sent_at = np.array(views.command_sent_at)
    newer = _newest(commands.receiver) & (commands.sent > command_sent_at[commands.receiver])
    inputs[commands.receiver[newer]] = commands.body[newer]
    sources[commands.receiver[newer]] = commands.sender[newer]
    command_sent_at[commands.receiver[newer]] = commands.sent[newer]
    return _views(time, received, sent_at, inputs, tuple(sources.tolist()), command_sent_at,
                  views.max_age)


def _newest(links: np.ndarray) -> np.ndarray:
    """Per message (oldest sent first), whether it is the last one on its link."""
    _, last_reversed = np.unique(links[::-1], return_index=True)
    newest = np.zeros(len(links), dtype=bool)
    newest[len(links) - 1 - last_reversed] = True
    return newest


def _views(time, states, sent_at, commands, command_from, command_sent_at,
           max_age) -> NetworkViews:
    return NetworkViews(float(time), frozen_array(states), frozen_array(sent_at),
                        frozen_array(commands), tuple(command_from),
                        frozen_array(command_sent_at), float(max_age))
