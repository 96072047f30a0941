"""Errors a user can act on. The CLI prints them as one line and exits with code 2."""


class InputError(ValueError):
    """Bad user input: the message names the input and what is wrong with it, in one line."""
