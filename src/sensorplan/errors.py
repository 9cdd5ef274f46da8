"""The one error type users see for bad input."""

from __future__ import annotations


class ConfigError(ValueError):
    """Invalid input, with the dotted path of the offending field.

    Parameters
    ----------
    field : str
        Dotted path of the field, e.g. ``"sensors[1].altitude"``.
    message : str
        What is wrong with it.
    """

    def __init__(self, field: str, message: str) -> None:
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}")

    def __reduce__(self) -> tuple[type, tuple[str, str]]:
        # Rebuild from (field, message) so the error crosses process boundaries intact.
        return (type(self), (self.field, self.message))
