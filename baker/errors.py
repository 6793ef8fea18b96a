"""One exception family for everything the user can cause.

The CLI catches `VoxgiError` and prints `error: <file>: <problem>` with exit
status 2; anything else is a bug and keeps its traceback.
"""


class VoxgiError(Exception):
    """Base of every error the user can cause. `path` names the file, if any."""

    def __init__(self, message: str, path=None):
        super().__init__(message)
        self.path = None if path is None else str(path)

    def one_line(self) -> str:
        msg = str(self).replace("\n", " ")
        return f"{self.path}: {msg}" if self.path else msg


class SceneError(VoxgiError):
    """The scene file is missing, unreadable or holds invalid geometry."""


class ConfigError(VoxgiError, ValueError):
    """A setting is unknown or out of range (a ValueError as well)."""


class BudgetError(VoxgiError):
    """A stage would need more memory than the configured budget."""


class BakeFileError(VoxgiError):
    """A bake file is damaged or not a voxgi bake."""


class GLError(VoxgiError):
    """No usable OpenGL context, or a shader failed to build."""


class VoxgiWarning(UserWarning):
    """Something the user should know that does not stop the work."""
