"""What a robot runs, for its carer's support person: ``daemon.version.version_text`` says the posed version
and, read from the models folder's manifest, the landmark models' converter version, mediapipe release and
ONNX hashes; a folder an earlier posed converted shows its own converter version; no folder says so and the fix.
(The text ``posed --version`` is to print once posed/cli.py uses it: see the report of this change.)"""

from __future__ import annotations

import json
import shutil

from posed.daemon.version import __version__, version_text
from posed.landmarks.model_pins import CONVERTER_VERSION, MEDIAPIPE_VERSION
from posed.landmarks.models import installed_models


def test_the_version_names_posed_and_the_models(models_dir):
    manifest = json.loads((models_dir / "manifest.json").read_text())
    first, second = version_text(str(models_dir)).splitlines()
    assert first == f"posed {__version__}"
    assert f"converter {CONVERTER_VERSION}, mediapipe {MEDIAPIPE_VERSION}" in second
    assert manifest["files"]["pose_landmark_full.onnx"]["sha256"][:12] in second and str(models_dir) in second
    models = installed_models(models_dir)
    assert models["converter_version"] == CONVERTER_VERSION and models["mediapipe"] == MEDIAPIPE_VERSION
    assert models["detector_onnx_sha256"] == manifest["files"]["pose_detection.onnx"]["sha256"]


def test_an_earlier_folder_shows_its_own_converter(models_dir, tmp_path):
    folder = tmp_path / "models"
    shutil.copytree(models_dir, folder)
    manifest = json.loads((folder / "manifest.json").read_text())
    manifest["converter_version"] = "1"
    (folder / "manifest.json").write_text(json.dumps(manifest))
    assert "converter 1, mediapipe" in version_text(str(folder))
    assert installed_models(folder)["converter_version"] == "1"


def test_no_models_says_so_and_the_fix(tmp_path):
    text = version_text(str(tmp_path / "none"))
    assert text.splitlines()[0] == f"posed {__version__}"
    assert "none usable in" in text and "posed models fetch" in text
    assert "error" in installed_models(tmp_path / "none")
