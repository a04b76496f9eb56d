"""open3d, imported where it is used (its import takes seconds)."""
from __future__ import annotations


def open3d():
    """The open3d module. Ctrl-C (or a `kill` handled as it) during its import raises
    KeyboardInterrupt, as anywhere else: open3d's extension turns it into
    ``ImportError("initialization failed")``, which would read as open3d missing."""
    try:
        import open3d as o3d
    except ImportError as e:
        if isinstance(e.__cause__ or e.__context__, KeyboardInterrupt):
            raise KeyboardInterrupt from e
        raise
    return o3d
