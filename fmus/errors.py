"""The FMU build's error, apart from the build (the command line catches it on every command,
and importing the build costs ~35 ms of each: modeldef's XML and its URL tools)."""


class BuildError(RuntimeError):
    """The FMU could not be built; the message carries the compiler's output."""
