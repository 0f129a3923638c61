"""Error types shared by both packages."""


class UserError(Exception):
    """Bad input from the user (a file, an option, a data row); the message names it and why.

    The CLI prints it as one line without a traceback and exits with status 2.
    """


class RejectedSample(Exception):
    """A grasp configuration that cannot yield trustworthy labels; `reason` is a short name."""

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason
        self.detail = detail
