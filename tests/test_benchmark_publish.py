"""The benchmark report is replaced only by a finished run (benchmarks/__main__.py ``publish``):
an interrupted run must not leave the published REPORT.md pointing at deleted figures."""
from benchmarks.__main__ import publish


def _report(folder, figures, text):
    (folder / "report").mkdir(parents=True, exist_ok=True)
    for name in figures:
        (folder / "report" / name).write_text(f"{text}:{name}")
    (folder / "REPORT.md").write_text(text)


def test_a_full_run_replaces_report_and_figures_and_drops_stale_ones(tmp_path):
    _report(tmp_path, ["a.png", "stale.png"], "old")
    staging = tmp_path / ".report-staging"
    _report(staging, ["a.png", "b.png", "results.json"], "new")
    publish(staging, tmp_path, replace_all=True)
    assert (tmp_path / "REPORT.md").read_text() == "new"
    assert sorted(p.name for p in (tmp_path / "report").iterdir()) == ["a.png", "b.png", "results.json"]
    assert (tmp_path / "report" / "a.png").read_text() == "new:a.png"
    assert not staging.exists()


def test_a_partial_run_replaces_only_its_own_figures(tmp_path):
    _report(tmp_path, ["a.png", "other.png"], "old")
    staging = tmp_path / ".report-staging"
    _report(staging, ["a.png"], "new")
    publish(staging, tmp_path, replace_all=False)
    assert (tmp_path / "report" / "other.png").read_text() == "old:other.png"
    assert (tmp_path / "report" / "a.png").read_text() == "new:a.png"


def test_an_interrupted_run_leaves_the_published_report_alone(tmp_path, monkeypatch):
    """main() stopped inside a section (here: the first one raises) never reaches publish."""
    import pytest
    import benchmarks.__main__ as bench
    _report(tmp_path, ["tve_cornell.png"], "old")

    def interrupted(ctx, scenes):
        (ctx.report_dir / "tve_cornell.png").write_text("half")   # a figure of the stopped run
        raise KeyboardInterrupt

    monkeypatch.setattr(bench.sections, "time_vs_error", interrupted)
    with pytest.raises(KeyboardInterrupt):
        bench.main(["--out", str(tmp_path), "--only", "tve"])
    assert (tmp_path / "REPORT.md").read_text() == "old"
    assert (tmp_path / "report" / "tve_cornell.png").read_text() == "old:tve_cornell.png"
