"""User-facing errors: each carries one line that names the problem and the fix.

run.py prints the message of any `UserError` on one line and exits with code 2;
anything else is a bug and keeps its traceback.
"""


class UserError(Exception):
    """Bad input from the user (config, files, hardware); message is shown as-is."""

    exit_code = 2


class ConfigError(UserError):
    """A config value is missing, of the wrong type or out of range."""


class DataError(UserError):
    """A file or data set is missing, unreadable or malformed."""


class HardwareError(UserError):
    """A device is missing, unconfigured or stopped answering."""


class NoDataError(UserError):
    """A run received no usable data (e.g. the field never saw a point)."""


class NumericalError(UserError):
    """NaN or inf where a finite number is required (a diverged optimisation, a bad pose)."""


class FrameSourceError(UserError):
    """The frames' producer (acquisition, rendering, classification) failed during a run;
    the run kept what it had mapped. The message names the error; its traceback is logged."""
