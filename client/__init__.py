"""posed's client: read a posed daemon (or a fleet of them behind a Zenoh router) from any Python program.

The message contract (formats, versions, JSON Schemas) is :mod:`client.contract`; the Zenoh client is
:class:`client.PosedClient` (docs/client.md). Imports zenoh, numpy, :mod:`camera_model`, the public result
types of :mod:`fitting` and :mod:`falls` and the landmark frame of :mod:`landmarks` (its parser reads the
landmarks topic as it reads a recording) only — never the daemon.
"""

__all__ = ["Alive", "HistoryEntry", "Landmarks", "PersonLandmarks", "PosedClient", "PosedClientError", "Restored",
           "RestoredFall", "State", "Status", "Watch", "restored", "session_config", "without_frames_s"]
_API = {"Alive", "PosedClient", "PosedClientError", "session_config"}


def __getattr__(name: str):
    if name in _API:
        from posed.client import api

        return getattr(api, name)
    if name in __all__:
        from posed.client import types

        return getattr(types, name)
    raise AttributeError(f"module 'client' has no attribute {name!r}")
