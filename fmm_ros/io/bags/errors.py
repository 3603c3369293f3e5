"""Errors of bag I/O: each names the bag and what is wrong with it, in words a user can act on.

All are `FmmError` subclasses (so ValueErrors), so the `fmm` command reports them as a
one-line error.
"""

from pathlib import Path

from fmm_ros.errors import BadInputError, DamagedFileError, FmmError


class BagError(FmmError):
    """A bag that cannot be read or written as asked."""


class BagDamagedError(BagError, DamagedFileError):
    """A bag is truncated or corrupt; every message before the damage was delivered first."""

    def __init__(self, path: Path, problems: list[str], messages_read: int) -> None:
        self.path = Path(path)
        self.problems = list(problems)
        self.messages_read = messages_read
        super().__init__(
            f'bag {self.path} is damaged: {"; ".join(self.problems)} '
            f'({messages_read} messages before the damage were read)'
        )


class MissingTopicError(BagError, BadInputError):
    """The bag lacks a topic the caller needs."""


class MessageTypeError(BagError, BadInputError):
    """A message type neither the bag nor fmm_ros defines, or not the type a topic needs."""
