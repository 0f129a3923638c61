"""Errors shared by every package of the project."""


class UserError(Exception):
    """Bad input from the user (a file, an option, a data row); the message names it and why.

    The CLI prints it as one line without a traceback and exits with status 2.
    """
