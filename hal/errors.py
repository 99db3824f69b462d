"""The errors of every source. All derive from :class:`SourceError`; each message names the camera or file
and says what to do.

``retry`` tells the caller whether reading the same source again makes sense:

==================  =====  =========================================================================
error               retry  meaning
==================  =====  =========================================================================
SourceNotFound      no     no such device or file (or nothing plugged in)
SourceUnsupported   no     hal cannot read this (format, missing pyrealsense2, a landmark recording)
SourceCorrupt       yes    data that cannot be decoded; the next read goes on after it
SourceTimeout       yes    no frame within the read timeout; the source is still there
SourceDisconnected  yes    the camera went away; the source reconnects by itself while it is read
EndOfStream         no     a recording has no more frames (``loop`` was off)
==================  =====  =========================================================================
"""

from __future__ import annotations


class SourceError(Exception):
    """Base of every hal error; ``source`` is the URI-like name of the camera or file (may be empty)."""

    retry = False

    def __init__(self, message: str, source: str = "") -> None:
        super().__init__(message)
        self.source = source


class SourceNotFound(SourceError):
    """The device or file does not exist (or no camera is plugged in)."""


class SourceUnsupported(SourceError):
    """The source exists but hal cannot read it (unknown format, missing library, landmark recording)."""


class SourceCorrupt(SourceError):
    """Data that cannot be decoded (a broken video, image or recording) or a frame larger than the reader
    takes (``pixels``: its width x height); reading may go on after it. ``fix``, when the source knows it,
    says what cures it (a covered lens is not cured by re-encoding a video)."""

    retry = True

    def __init__(self, message: str, source: str = "", pixels: int | None = None, fix: str = "") -> None:
        super().__init__(message, source)
        self.pixels = pixels
        self.fix = fix


class SourceTimeout(SourceError):
    """No frame arrived within the read timeout; the source is still open."""

    retry = True


class SourceDisconnected(SourceError):
    """The camera was unplugged or stopped answering; the source keeps trying to reconnect while read."""

    retry = True


class EndOfStream(SourceError):
    """A recording has no more frames."""
