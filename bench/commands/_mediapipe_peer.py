"""Runs MediaPipe 0.10.21 itself (legacy ``solutions.pose``, full model) for ``posed bench peer``.

Not part of posed: this file is executed by the Python of a separate virtual environment that has
``mediapipe==0.10.21`` (it needs numpy<2), e.g.::

    python3.11 -m venv /opt/mediapipe-peer && /opt/mediapipe-peer/bin/pip install mediapipe==0.10.21 'numpy<2'

It imports nothing from posed. Reads one JSON object on stdin — ``{"images": [{"name", "path"}, ...],
"video": path or null, "video_fps": 30}`` — and writes one JSON object on stdout: per image the 33 landmarks in
pixels ``[[x, y, visibility], ...]`` (static-image mode, a fresh graph per image) or null when nobody is
found; for the video the landmarks of every frame in tracking mode and the median milliseconds per frame.
The legacy API stamps frames 1/30 s apart whatever the video's rate (``solution_base.py``).
"""

import json
import sys
import time

import cv2
import mediapipe as mp


def landmarks_px(result, width, height):
    if result.pose_landmarks is None:
        return None
    return [[p.x * width, p.y * height, p.visibility] for p in result.pose_landmarks.landmark]


def main():
    request = json.load(sys.stdin)
    pose_api = mp.solutions.pose
    out = {"mediapipe": mp.__version__, "images": {}, "video": None}
    for item in request["images"]:
        image = cv2.imread(item["path"])
        h, w = image.shape[:2]
        with pose_api.Pose(static_image_mode=True, model_complexity=1) as pose:
            out["images"][item["name"]] = landmarks_px(pose.process(cv2.cvtColor(image, cv2.COLOR_BGR2RGB)), w, h)
    if request.get("video"):
        cap = cv2.VideoCapture(request["video"])
        frames, times = [], []
        with pose_api.Pose(static_image_mode=False, model_complexity=1) as pose:
            while True:
                ok, image = cap.read()
                if not ok:
                    break
                h, w = image.shape[:2]
                t0 = time.perf_counter()
                result = pose.process(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
                times.append((time.perf_counter() - t0) * 1e3)
                frames.append(landmarks_px(result, w, h))
        cap.release()
        times.sort()
        out["video"] = {"frames": frames, "median_ms": times[len(times) // 2] if times else None}
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
