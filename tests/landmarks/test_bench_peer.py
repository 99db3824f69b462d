"""``posed bench peer``: MediaPipe itself runs in a separate venv (not installed by `make test`), so here only
the command's refusal without it; the measured numbers live in docs/benchmarks.md."""

from posed.cli import main


def test_without_a_mediapipe_python_it_names_the_recipe(monkeypatch, tmp_path, capsys):
    monkeypatch.delenv("POSED_MEDIAPIPE_PYTHON", raising=False)
    assert main(["bench", "peer", "--mediapipe-python", str(tmp_path / "nowhere" / "python")]) == 2
    err = capsys.readouterr().err
    assert "mediapipe==0.10.21" in err and "numpy<2" in err and "--mediapipe-python" in err
