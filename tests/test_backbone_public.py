"""Backbones of the public data sets (numbers quoted in docs/public-data.md, section 5)."""

from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
pytestmark = [pytest.mark.filterwarnings("ignore"), pytest.mark.slow]


@pytest.mark.skipif(not (DATA / "unesp_bolted_beam").exists(), reason="UNESP data not available")
def test_unesp_backbone_softens_and_damps_more():
    from jointid.app.public_backbones import unesp_backbone

    r = unesp_backbone()
    b = r.backbones[0].sorted()
    assert len(b) == 4
    f = b.frequency_hz
    assert f[2:].max() < f[:2].min()  # softening: the two large-amplitude dwells sit lower
    assert f[0] < r.reference["f1_hz_random_test"] and abs(f[0] / 18.75 - 1) < 0.005
    assert 0.85 < f[-1] / f[0] < 1.0 and b.zeta[-1] > 1.5 * b.zeta[0] > 0
    assert np.allclose(f, [18.693, 18.700, 18.576, 18.538], atol=0.002)


@pytest.mark.skipif(not (DATA / "silverbox_multilevel_noel").exists(), reason="Silverbox data not available")
def test_silverbox_backbones_start_at_the_reference():
    from jointid.app.public_backbones import silverbox_backbone

    r = silverbox_backbone()
    assert len(r.backbones) == 5
    for b in r.backbones:
        assert abs(b.frequency_hz[0] / r.reference["f1_hz"] - 1) < 1e-3
        assert abs(b.zeta[0] - r.reference["zeta"]) < 0.003
        assert np.all(np.diff(b.omega) >= -1e-9)  # hardening
        assert b.decades() >= 1.47
    top = r.backbones[-1]
    assert 100 < top.frequency_hz[-1] < 110
