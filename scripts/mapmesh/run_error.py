"""The launcher's one error type (its own module, so that every part can raise it)."""


class RunError(Exception):
    """A failure with a one-line reason; `exit_code` is the launcher's exit status."""

    def __init__(self, message, exit_code=1):
        super().__init__(message)
        self.exit_code = exit_code
