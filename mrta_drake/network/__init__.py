"""The network the robots' cluster messages travel over: ``BroadcastNetwork``, a block between
the robots, the controller and back (docs/fidelity.md#communication), used when the
scenario's ``communication:`` is not ideal."""

from mrta_drake.network.broadcast_network import BroadcastNetwork

__all__ = ["BroadcastNetwork"]
