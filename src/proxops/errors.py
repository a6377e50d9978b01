"""Errors that tell the user what to do.

Every input problem raises :class:`ProxopsInputError` with a one-line message naming
the field, the bad value, its unit and what is allowed. The CLI prints that line and
exits with code 2 (a traceback only with ``--debug``).
"""


class ProxopsError(Exception):
    """Base class of every proxops error."""


class PlantEnded(ProxopsError):
    """The plant cannot go on for a physical reason (e.g. the target re-entered): the engine ends
    the run there with ``outcome`` and ``StopReason.PLANT``; not an internal error."""

    def __init__(self, outcome: str):
        super().__init__(outcome)
        self.outcome = outcome


class ProxopsInputError(ProxopsError, ValueError):
    """Bad user input: scenario key, CLI option or function argument."""


def input_error(field: str, value, allowed: str, unit: str = "") -> ProxopsInputError:
    """Build the standard one-line message: ``field = value unit: allowed``."""
    unit_text = f" {unit}" if unit else ""
    return ProxopsInputError(f"{field} = {value!r}{unit_text}: {allowed}")
