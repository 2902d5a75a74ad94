"""The mirror sheet (`python -m study scenes --sheet PNG`, issue 41 item 7): from given crops and
scores, one row per scene of four labelled cells (truth | default | on-set probe | plate mean),
each crop shown as given with its PSNR and FLIP under it; the dozen scenes it draws; a path
that is not a PNG is a one-line usage error. No rendering (bpy is imported, not run)."""

import numpy as np
import pytest

pytest.importorskip("bpy", reason="the 3D study's report imports its bpy renderer")

from study import cli  # noqa: E402
from study.scenes3d import report, sheet  # noqa: E402

DEFAULT = "Camera View + Ground"
COLUMNS = ("Truth", DEFAULT, report.PROBE, report.MEAN)


def _rows(n):
    rng = np.random.default_rng(7)
    rows = []
    for i in range(n):
        shape = (20 + 3 * i, 30 + 2 * i, 3)  # crops of different sizes, as subjects are
        crops = {c: rng.random(shape) for c in COLUMNS}
        scores = {
            c: {"psnr": 10.0 + i + 0.25 * k, "flip": 0.3 + 0.01 * i + 0.1 * k}
            for k, c in enumerate(COLUMNS[1:])
        }
        rows.append(
            (f"s{200 + i}_sphere_forest", "held out" if i % 2 else "Poly Haven", crops, scores)
        )
    return rows


def test_the_sheet_lays_out_n_rows_of_four_labelled_cells():
    rows = _rows(3)
    fig = report.sheet_figure(rows, DEFAULT)
    axes = fig.axes
    assert len(axes) == 3 * 4
    for j, column in enumerate(report.SHEET_COLUMNS):  # the titles over the first row only
        assert axes[j].get_title() == report.SHEET_TITLES[column]
        assert axes[4 + j].get_title() == ""
    for i, (name, tag, crops, scores) in enumerate(rows):
        for j, column in enumerate(COLUMNS):
            ax = axes[4 * i + j]
            (image,) = ax.get_images()
            np.testing.assert_array_equal(image.get_array(), crops[column])
            text = ax.get_xlabel()
            if column == "Truth":
                assert name in text and tag in text
            else:
                assert f"{scores[column]['psnr']:.1f} dB" in text
                assert f"FLIP {scores[column]['flip']:.2f}" in text


def test_the_sheet_is_written_as_a_png(tmp_path):
    path = tmp_path / "sheet.png"
    report.write_sheet(_rows(2), DEFAULT, path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_sheet_draws_six_held_out_and_six_poly_haven_scenes():
    drawn = sheet.specs()
    tags = [tag for _, tag in drawn]
    assert tags == ["held out"] * 6 + ["Poly Haven"] * 6
    assert {s.hdri for s, tag in drawn if tag == "held out"} == {"forest", "night"}
    assert all(s.hdri.startswith("ph_") for s, tag in drawn if tag == "Poly Haven")
    assert len({s.name for s, _ in drawn}) == 12


def test_a_sheet_that_is_not_a_png_is_a_one_line_usage_error(tmp_path, capsys):
    assert cli.main(["scenes", "--sheet", str(tmp_path / "sheet.jpg")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--sheet" in err and ".png" in err
    assert not (tmp_path / "sheet.jpg").exists()


def test_the_means_line_averages_each_column_per_set():
    def record(name, ours, probe):
        scores = {
            DEFAULT: {"psnr": ours, "flip": 0.5},
            report.PROBE: {"psnr": probe, "flip": 0.2},
            "(plate itself)": {"psnr": 0.0, "flip": 1.0},
        }
        return {"scene": {"name": name}, "results": {"mirror": scores}}

    line = sheet.means_line(
        [record("s201_sphere_forest", 12.0, 18.0), record("s202_sphere_night", 14.0, 20.0)]
    )
    assert line.startswith("means: held out (2): ")
    assert f"{DEFAULT} 13.00 dB / FLIP 0.500" in line and "On-set probe 19.00 dB" in line
    assert "Poly Haven" not in line and "plate itself" not in line
