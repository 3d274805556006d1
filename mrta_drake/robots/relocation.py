"""Lift rides' relocations as a robots block takes them: each pose once, when new."""

from dataclasses import dataclass

from mrta_drake.payloads import Relocations


@dataclass(frozen=True)
class Applied:
    """A robots block's state: per robot, the sequence number of the last relocation
    applied (0: none)."""

    seen: tuple[int, ...]

    def __deepcopy__(self, memo):
        return self  # immutable: Drake's copies of the state at each update can share it

    def new_moves(self, relocations: Relocations) -> tuple:
        """Per robot, its move in ``relocations`` (``(sequence, (x, y, theta))``) if its
        sequence number is new, else None; None for robots past the end of the moves."""
        moves = relocations.moves
        return tuple(moves[k] if k < len(moves) and moves[k] is not None
                     and moves[k][0] > seen else None
                     for k, seen in enumerate(self.seen))

    def after(self, moves: tuple) -> "Applied":
        """This record once the ``new_moves`` ``moves`` are applied."""
        return Applied(tuple(seen if move is None else move[0]
                             for seen, move in zip(self.seen, moves, strict=True)))
