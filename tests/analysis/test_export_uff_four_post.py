"""The four-post sweep's FRFs as UFF 58 records (``bench.export.uff58``), read back by pyuff: each
FRF over Z followed by its coherence and its standard uncertainty, the ratios over the contact force
by their uncertainty, on the even abscissa of the Welch bins, with the degrees of freedom that say
which force each is. On both four-post runs of the analysis tests (Model 2 and 3 cars), whose
fixtures those tests make anyway."""

from __future__ import annotations

import numpy as np
import pytest
import pyuff

from bench.export.uff58 import CONTACT_NODE, WHEEL_NODE, four_post_functions, write_uff58


def test_four_post_frfs_read_back_with_coherence_and_uncertainty(four_post_analysis, tmp_path):
    _, result = four_post_analysis
    out = tmp_path / "four_post.uff"
    write_uff58(four_post_functions(result, "paper-s010-sweep"), ("campaign.h5", "27-NOV-26 10:00:00"), out)
    sets = pyuff.UFF(str(out)).read_sets()[1:]  # after the units record
    f = result.frfs.wfs_per_z.freq_hz
    kinds = [(s["id1"].strip(), s["func_type"]) for s in sets]
    over_z = ["F_WFS/Z", "F_contact/Z", "a_hub/Z", "F_WFS hub-compensated/Z", "F_WFS model-compensated/Z"]
    ratios = ["F_WFS/F_contact raw", "F_WFS hub-compensated/F_contact", "F_WFS model-compensated/F_contact"]
    assert kinds == [
        *(
            k
            for what in over_z
            for k in ((what, 4), (f"coherence of {what}", 6), (f"standard uncertainty of {what}", 0))
        ),
        *(k for what in ratios for k in ((what, 4), (f"standard uncertainty of {what}", 0))),
    ]
    by_title = {s["id1"].strip(): s for s in sets}
    for s in sets:  # the Welch bins: an even abscissa from the first bin, its step the resolution
        assert s["abscissa_spacing"] == 1
        assert s["abscissa_min"] == pytest.approx(f[0], rel=1e-5)
        assert s["abscissa_inc"] == pytest.approx(f[1] - f[0], rel=1e-5)
        assert s["num_pts"] == f.size
        assert s["z_axis_value"] == pytest.approx(result.amplitude_m, rel=1e-5)
    np.testing.assert_allclose(by_title["F_WFS/Z"]["data"], result.frfs.wfs_per_z.value, rtol=1e-11)
    np.testing.assert_allclose(
        by_title["coherence of a_hub/Z"]["data"], result.frfs.sweeps["a_hub"].coherence, rtol=1e-11
    )
    raw = by_title["F_WFS/F_contact raw"]
    np.testing.assert_allclose(raw["data"], result.wfs_per_contact.value, rtol=1e-11)
    assert (raw["rsp_ent_name"].strip(), raw["rsp_node"], raw["ref_ent_name"].strip(), raw["ref_node"]) == (
        "WFS",
        WHEEL_NODE,
        "CONTACT",
        CONTACT_NODE,
    )
    hub = by_title["F_WFS hub-compensated/F_contact"]
    assert hub["rsp_ent_name"].strip() == "WFS+HUB"
    np.testing.assert_allclose(
        by_title["standard uncertainty of F_WFS hub-compensated/F_contact"]["data"],
        result.hub_compensated_per_contact.sigma,
        rtol=1e-11,
    )
    # coherence is a fraction: the reader sees it as one
    assert all(0 <= c <= 1 + 1e-9 for c in by_title["coherence of F_WFS/Z"]["data"])
