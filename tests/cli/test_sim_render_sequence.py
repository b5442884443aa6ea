"""``dptpu sim render --sequence``: absurd sequences are refused before anything is rendered (issue 19).

Before, ``--sequence 1e308x4`` rendered the scene and failed late in the noise model (``lam value too large``) and
``16x100000`` was killed for memory after minutes; now both are one line naming ``--sequence`` and the range, exit 2,
and no output folder.
"""
from __future__ import annotations

import pytest

from dptpu.cli.main import main
from dptpu.sim.image_formation import parse_sequences


@pytest.mark.parametrize(("sequence", "expected"), [
    ("1e308x4", "--sequence '1e308x4': frequency must be in (0, 456] (a period of at least 2 projector pixels "
                "over its 912 pixels along x); got 1e+308"),
    ("16x4,600x4:y", "--sequence '600x4:y': frequency must be in (0, 570]"),
    ("16x100000", "--sequence '16x100000': steps must be an integer in [3, 1000]; got 100000"),
    ("infx4", "--sequence 'infx4': sequence frequency must be a number > 0; got inf"),
])
def test_absurd_sequence_is_refused_before_rendering(tmp_path, capsys, sequence, expected):
    out = tmp_path / "capture"
    code = main(["sim", "render", "--rig", "nominal", "--scene", "sphere", "--sequence", sequence,
                 "--size", "32x24", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and expected in err, err
    assert not out.exists()


@pytest.mark.parametrize("projector_size", [(1280, 800), (640, 360), (1920, 1080)])
def test_the_projectable_limit_is_half_the_projector_extent_along_the_fringe_axis(projector_size):
    width, height = projector_size  # projectors other than the nominal rig's 912x1140
    assert [s.frequency for s in parse_sequences(f"{width / 2}x3,{height / 2}x3:y",
                                                 projector_size=projector_size)] == [width / 2, height / 2]
    for token in (f"{width / 2 + 0.5}x3", f"{height / 2 + 0.5}x3:y"):
        with pytest.raises(ValueError, match=r"frequency must be in \(0, "):
            parse_sequences(token, projector_size=projector_size)
