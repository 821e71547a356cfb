"""Progress without a terminal is plain lines, never carriage returns."""

from __future__ import annotations

from hola_ray.progress import PlainProgress, progress


def test_without_a_terminal_progress_is_plain_lines(capsys, monkeypatch):
    monkeypatch.setattr(PlainProgress, "interval_s", 0.0)
    with progress(1000, "gen 3 oracle", "step") as bar:  # stderr is captured: no terminal
        assert isinstance(bar, PlainProgress)
        for _ in range(4):
            bar.update(250)
            bar.set_postfix(ret="1.5", sps="900")
    err = capsys.readouterr().err
    assert "\r" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 5  # one per update (interval 0) and one at the end
    assert lines[-1].startswith("gen 3 oracle: 1,000 / 1,000 step (100%)")
    assert lines[-1].endswith("; ret 1.5, sps 900")


def test_a_disabled_progress_says_nothing(capsys):
    with progress(10, "quiet", "ep", enabled=False) as bar:
        bar.update(10)
    assert capsys.readouterr().err == ""
