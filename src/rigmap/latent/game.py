"""Noughts and crosses for the latent face (Bailey et al. 2016 §7's Tic-Tac-Toe demo): the
board, the event each move makes, and the commands the face plays for an event.

Shared by ``rigmap synth demo`` (two seeded random players, headless) and the studio's
Play view (the user, X, against the computer, O). X is "us": its moves are ``own_move``,
O's ``opponent_move``, or ``threat`` when O then has two in a line with the third cell
free; a line of X is a ``win``, a line of O a ``loss``, a full board without one a
``draw``. Which emotion each event plays is ours (the paper's game picks per event).
"""

from __future__ import annotations

#: each event and the emotion the face plays for it (ours)
EVENT_EMOTIONS = {
    "own_move": "curious",
    "opponent_move": "neutral",
    "threat": "grumpy",
    "win": "happy",
    "loss": "roar",
    "draw": "bored",
}
LINES = [(0, 1, 2), (3, 4, 5), (6, 7, 8), (0, 3, 6), (1, 4, 7), (2, 5, 8), (0, 4, 8), (2, 4, 6)]
PLAYERS = ("x", "o")  # x moves first


class GameError(ValueError):
    """A move the rules refuse (a taken cell, a finished game, no such cell)."""


class Board:
    """Nine cells, ``None`` or a player, in reading order (0 top left, 8 bottom right)."""

    def __init__(self):
        self.cells: list[str | None] = [None] * 9

    def free(self) -> list[int]:
        return [k for k in range(9) if self.cells[k] is None]

    def winner(self) -> str | None:
        for line in LINES:
            first = self.cells[line[0]]
            if first is not None and all(self.cells[k] == first for k in line):
                return first
        return None

    @property
    def over(self) -> bool:
        return self.winner() is not None or not self.free()

    @property
    def turn(self) -> str:
        """Whose move is next (X after an equal count)."""
        return "x" if self.cells.count("x") == self.cells.count("o") else "o"

    def play(self, cell: int, player: str) -> list[str]:
        """Put ``player`` on ``cell``: the move's event, then ``draw`` if it filled the board."""
        if player not in PLAYERS:
            raise GameError(f"player {player!r}: expected one of {PLAYERS}")
        if self.over:
            raise GameError("the game is over; start a new one")
        if player != self.turn:
            raise GameError(f"it is {self.turn.upper()}'s turn, not {player.upper()}'s")
        if not (isinstance(cell, int) and 0 <= cell < 9) or self.cells[cell] is not None:
            raise GameError(f"cell {cell!r} is not free; free cells: {self.free()}")
        self.cells[cell] = player
        if self.winner() == player:
            return ["win" if player == "x" else "loss"]
        two = any(
            sum(self.cells[k] == "o" for k in line) == 2
            and any(self.cells[k] is None for k in line)
            for line in LINES
        )
        mover = "own" if player == "x" else "opponent"
        kind = "threat" if two and player == "o" else f"{mover}_move"
        return [kind, "draw"] if not self.free() else [kind]

    def completing(self, player: str) -> list[int]:
        """Free cells that would give ``player`` a line."""
        found = []
        for line in LINES:
            marks = [self.cells[k] for k in line]
            if marks.count(player) == 2 and marks.count(None) == 1:
                found.append(line[marks.index(None)])
        return sorted(set(found))


def game_events(rng) -> list[tuple[str, str]]:
    """One random game: ``(player, event)`` per turn, ``player`` "x" (us) or "o" ("-" for
    a draw)."""
    board, events = Board(), []
    for turn in range(9):
        player = "x" if turn % 2 == 0 else "o"
        for kind in board.play(int(rng.choice(board.free())), player):
            events.append(("-" if kind == "draw" else player, kind))
        if board.over:
            break
    return events


def computer_move(board: Board, rng, player: str = "o") -> int:
    """The computer's cell (ours): complete its own line if it can, else block the other
    player's, else a free cell drawn from ``rng``."""
    other = "x" if player == "o" else "o"
    for cells in (board.completing(player), board.completing(other)):
        if cells:
            return cells[0]
    return int(rng.choice(board.free()))


def emotion_commands(fitted, model_now: str, emotion: str, rng) -> list:
    """TRANSITION to ``emotion`` (if it is a model) and PLAY one of its takes."""
    from rigmap.latent.synthesis import Idle, Play, Transition

    target = emotion if emotion in fitted.models else model_now
    commands = [] if target == model_now else [Transition(target)]
    names = fitted.sets[target].names
    return [*commands, Play(names[int(rng.integers(len(names)))]), Idle(6)]
