"""``posed config check --source URI``: open the source, read its first frames, and say what it delivers (size,
orientation, rate, length) and what the daemon will do with it (the working size it scales frames down to,
which frames it takes at ``pipeline.target_fps``, pacing), with the same functions the capture stage uses."""

from __future__ import annotations

import dataclasses

FIRST_READS = 5          # reads tried for a first frame (a camera's first reads may time out)


def probe(cfg) -> tuple[list[str], list[str]]:
    """(lines to print, problems) for the source of ``cfg`` (a resolved config)."""
    from posed import hal

    src = cfg.source
    if src.type == "file" and hal.is_landmark_recording(src.path):
        return _landmark_recording(cfg)
    try:
        source = hal.open_source(dataclasses.replace(src, realtime=False) if src.type == "file" else src)
        source.open()
    except hal.SourceError as exc:
        return [], [f"source: {exc}"]
    try:
        frame, errors = None, []
        for _ in range(FIRST_READS):
            try:
                frame = source.read(src.read_timeout_s)
                break
            except hal.EndOfStream as exc:
                errors.append(str(exc))
                break
            except hal.SourceError as exc:
                errors.append(str(exc))
        info = source.info
    finally:
        source.close()
    if frame is None:
        what = "; ".join(dict.fromkeys(errors)) or "no frame"
        return [], [f"source: {to_uri(cfg)} gave no frame in {FIRST_READS} reads: {what}; the daemon would be "
                    "blind on it"]
    return _describe(cfg, info, frame), []


def to_uri(cfg) -> str:
    from posed.hal import to_uri as uri

    return uri(cfg.source)


def _describe(cfg, info: dict, frame) -> list[str]:
    from posed.hal import scale_factor, working_size

    w, h = frame.width, frame.height
    fps = float(info.get("fps") or 0.0)
    kind = info.get("kind", cfg.source.type)
    what = {"file": "a recording", "v4l2": "a V4L2 camera", "realsense": "a RealSense camera"}.get(kind, kind)
    parts = [f"{w}x{h}" + (" portrait" if h > w else ""), f"{fps:g} fps" if fps else "fps unknown"]
    if info.get("codec"):
        parts.append(str(info["codec"]))
    if info.get("frame_count"):
        n = int(info["frame_count"])
        parts.append(f"{n} frames" + (f" ({n / fps:.1f} s)" if fps else ""))
    if info.get("rotation"):
        parts.append(f"rotation tag {info['rotation']} deg: played upright")
    if frame.depth is not None:
        parts.append("depth aligned to colour")
    if frame.intrinsics is not None:
        parts.append(f"fx {frame.intrinsics.fx:g} px")
    lines = [f"source: {to_uri(cfg)}: {what}, " + ", ".join(parts)]
    p = cfg.pipeline
    k = scale_factor(w, h, p.frame_max_pixels)
    if k > 1:
        ww, wh = working_size(w, h, p.frame_max_pixels)
        lines.append(f"  the daemon scales each frame down by {k} to {ww}x{wh} (area interpolation; "
                     f"pipeline.frame_max_pixels {p.frame_max_pixels}) for the landmark stage; landmarks, "
                     f"image_size and intrinsics stay in the source's {w}x{h} pixels")
    else:
        lines.append(f"  the daemon works on the frames at their own size ({w}x{h} is within "
                     f"pipeline.frame_max_pixels {p.frame_max_pixels})")
    if fps and fps > p.target_fps * 1.05:
        lines.append(f"  it takes {p.target_fps:g} of the {fps:g} frames per second (pipeline.target_fps), by "
                     "capture time")
    elif fps:
        lines.append(f"  it takes every frame ({fps:g} fps is within pipeline.target_fps {p.target_fps:g}); poses "
                     f"come at {fps:g} per second")
    if kind == "file":
        pace = ("paced by the recording's timestamps, as a camera would deliver it (source.realtime)"
                if cfg.source.realtime else "as fast as the pipeline takes it, losing no frame (source.realtime "
                                            "false)")
        end = "stops at its end (pipeline.stop_at_end)" if p.stop_at_end else (
            "starts again at its end (source.loop)" if cfg.source.loop else "then idles (pipeline.stop_at_end "
                                                                              "false)")
        lines.append(f"  the replay runs {pace} and {end}")
    return lines


def _landmark_recording(cfg) -> tuple[list[str], list[str]]:
    from posed.landmarks import RecordingError, RecordingProblem, iter_recording

    try:
        header, stream = iter_recording(cfg.source.path)
        frames = sum(1 for item in stream if not isinstance(item, RecordingProblem))
    except (RecordingError, OSError) as exc:
        return [], [f"source: {exc}"]
    w, h = header.image_size
    return [f"source: {to_uri(cfg)}: a landmark recording, {w}x{h}, {header.fps:g} fps, {frames} frames",
            "  the daemon replays it straight to the fitting stage (no camera, no landmark stage), taking at most "
            f"{cfg.pipeline.target_fps:g} frames per second"], []
