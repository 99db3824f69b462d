"""Wrong files and bad options: one clear line and a non-zero exit, never a traceback or a page of per-line
complaints; a crafted huge image in a folder is left out and the run goes on; a truncated model is called
truncated, not missing; a --set problem is blamed on the --set."""

from __future__ import annotations

import os
import shutil

import pytest

from posed.cli import main
from tests.cli_safety.conftest import huge_png, posed


def _usage_error(capsys, argv: list[str], *words: str) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err, err
    return err


def test_plot_fit_of_binary_files(fit_file, tmp_path, capsys):
    binary = tmp_path / "blob.bin"
    binary.write_bytes(bytes(range(256)) * 8)
    png = tmp_path / "p.png"
    assert main(["plot", "fit", str(binary), "-o", str(png)]) == 2
    err = capsys.readouterr().err
    assert f"{binary} is not UTF-8 text, so not fit results" in err and "Traceback" not in err
    assert main(["plot", "fit", str(fit_file), "--events", str(binary), "-o", str(png)]) == 2
    err = capsys.readouterr().err
    assert f"{binary} is not UTF-8 text, so not fall events" in err
    late = tmp_path / "late.jsonl"             # text first, a bad byte after the first 4 kB
    late.write_bytes(fit_file.read_bytes() + b"\xff\xfe\n")
    assert main(["plot", "fit", str(late), "-o", str(png)]) == 2
    assert "is not UTF-8 text (byte 0xff)" in capsys.readouterr().err
    assert not png.exists()


def test_plot_width_is_checked(fit_file, tmp_path, capsys):
    png = str(tmp_path / "p.png")
    _usage_error(capsys, ["plot", "fit", str(fit_file), "--width", "-5", "-o", png], "--width", "out of range")
    _usage_error(capsys, ["plot", "history", "--width", "0", "-o", png], "--width", "from 200 to 10000 pixels")
    _usage_error(capsys, ["plot", "history", "--width", "99999", "-o", png], "--width")


def test_plot_fit_of_a_landmark_recording_says_so_in_one_line(tiny, tmp_path, capsys):
    assert main(["plot", "fit", str(tiny), "-o", str(tmp_path / "p.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"posed plot fit: {tiny} is a landmark recording, not fit results: run "
                   f"`posed fit {tiny} -o FIT.jsonl` first and plot FIT.jsonl"]


def test_fit_of_an_image_names_posed_landmarks(shared_data, capsys):
    image = shared_data / "reference" / "mediapipe_pose_jpg" / "pose.jpg"
    assert main(["fit", str(image)]) == 2
    err = capsys.readouterr().err
    assert "looks like an image (JPEG), not a landmark recording" in err and f"posed landmarks {image}" in err


def test_landmarks_leaves_out_a_huge_image_and_goes_on(shared_data, tmp_path):
    folder = tmp_path / "images"
    folder.mkdir()
    huge_png(folder / "a_huge.png")
    shutil.copy(shared_data / "reference" / "mediapipe_pose_jpg" / "pose.jpg", folder / "b.jpg")
    out = tmp_path / "out.landmarks.jsonl"
    r = posed("landmarks", str(folder), "-o", str(out))
    assert r.returncode == 1, r.stderr
    assert "Traceback" not in r.stderr and "cv2.error" not in r.stderr
    assert f"{folder / 'a_huge.png'}: image too large: 60000 x 60000, at most 33177600 pixels" in r.stderr
    lines = out.read_text().splitlines()
    assert len(lines) == 2 and '"seq": 1' in lines[1]          # the header and the later image's frame
    r = posed("landmarks", str(folder / "a_huge.png"), "-o", str(tmp_path / "one.jsonl"))
    assert r.returncode == 2 and "image too large: 60000 x 60000" in r.stderr and "Traceback" not in r.stderr


def test_landmarks_fps_must_be_positive(tmp_path, capsys):
    for bad in ("0", "-5", "nan"):
        _usage_error(capsys, ["landmarks", str(tmp_path), "--fps", bad], "--fps")


def test_a_truncated_model_is_called_truncated(tmp_path):
    from posed.landmarks import find_models

    src = find_models(None).models_dir
    models = tmp_path / "models"
    models.mkdir()
    for f in src.iterdir():
        if f.name == "pose_landmark_full.onnx":
            with open(f, "rb") as fh:
                (models / f.name).write_bytes(fh.read(5_000_000))
        else:
            os.symlink(f, models / f.name)             # read only: the originals are never touched
    r = posed("config", "check", "--set", f"landmarks.models_dir={models}")
    assert r.returncode == 78, r.stderr
    assert "pose_landmark_full.onnx is truncated: 5000000 bytes" in r.stderr, r.stderr
    assert "is missing" not in r.stderr and "posed models fetch" in r.stderr


def test_events_and_history_options(tmp_path, history_db, capsys):
    folder = tmp_path / "emptydir"
    folder.mkdir()
    assert main(["events", "--journal", str(folder)]) == 2
    assert f"{folder} is a folder, not an event journal" in capsys.readouterr().err
    _usage_error(capsys, ["events", "--limit", "-3"], "--limit", "must be at least 1")
    _usage_error(capsys, ["events", "--limit", "0"], "--limit")
    assert main(["events", "--journal", str(tmp_path / "e.sqlite3"), "--since", "1h", "--until", "2h"]) == 2
    assert "is after --until 2h" in capsys.readouterr().err
    assert main(["history", "--db", str(history_db), "--since", "2024-05-02", "--until", "2024-05-01"]) == 2
    assert "--since 2024-05-02" in capsys.readouterr().err


def test_a_set_problem_is_blamed_on_the_set(capsys):
    assert main(["config", "check", "--set", "nokey=1"]) == 78
    err = capsys.readouterr().err
    assert err.startswith("--set nokey=1: nokey: unknown key"), err
    assert "config.yaml" not in err
