"""posed's client: read a posed daemon (or a fleet of them behind a Zenoh router) from any Python program.

The message contract (formats, versions, JSON Schemas) is :mod:`client.contract`; the Zenoh client is
:class:`client.PosedClient` (docs/client.md). Imports zenoh, numpy, :mod:`camera_model`, the public result
types of :mod:`fitting` and :mod:`falls` and the landmark frame of :mod:`landmarks` (its parser reads the
landmarks topic as it reads a recording) only — never the daemon. :mod:`client.mount` builds the one message a
robot's own software puts (where the camera is: ``PosedClient.set_camera_mount``) and its geometry.
"""

__all__ = ["Alive", "CameraMount", "HistoryEntry", "Landmarks", "PersonLandmarks", "PosedClient", "PosedClientError",
           "Presence", "PrivacyState", "Restored", "RestoredFall", "State", "Status", "Watch", "absence_note",
           "camera_mount_message", "dark_note", "mount_from_rotation", "presence_change", "presence_note",
           "quaternion_matrix", "restored", "session_config", "without_frames_s"]
_API = {"Alive", "PosedClient", "PosedClientError", "session_config"}
_MOUNT = {"CameraMount", "camera_mount_message", "mount_from_rotation", "quaternion_matrix"}


def __getattr__(name: str):
    if name in _API:
        from posed.client import api

        return getattr(api, name)
    if name in _MOUNT:
        from posed.client import mount

        return getattr(mount, name)
    if name in __all__:
        from posed.client import types

        return getattr(types, name)
    raise AttributeError(f"module 'client' has no attribute {name!r}")
