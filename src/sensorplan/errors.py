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


#: Longest field and message shown in an error line (characters); the rest is elided.
MAX_FIELD_CHARS = 120
MAX_MESSAGE_CHARS = 400


def _printable(text: str, limit: int, spaces: bool = False) -> str:
    """``text`` safe for a terminal: control characters and lone surrogates as escapes
    (``\\x1b``, ``\\ud800``; with ``spaces``, line breaks and tabs as spaces), cut to
    ``limit`` characters with ``...``."""
    out = []
    for ch in text:
        code = ord(ch)
        if spaces and ch in "\r\n\t":
            out.append(" ")
        elif code < 0x20 or 0x7F <= code < 0xA0:
            out.append(f"\\x{code:02x}")
        elif 0xD800 <= code <= 0xDFFF or code in (0x2028, 0x2029):
            out.append(f"\\u{code:04x}")
        else:
            out.append(ch)
        if len(out) > limit:
            break
    shown = "".join(out)
    return shown if len(shown) <= limit else shown[:limit - 3] + "..."


def error_line(field: str, message: str) -> str:
    """The one stderr line of a bad input: ``error: <field>: <message>`` (no newline), with
    control characters escaped and over-long parts cut (a 100 kB value is not echoed)."""
    return f"error: {_printable(str(field), MAX_FIELD_CHARS)}: " \
           f"{_printable(str(message), MAX_MESSAGE_CHARS, spaces=True)}"
