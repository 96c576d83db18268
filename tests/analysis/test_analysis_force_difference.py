"""The paper's Fig. 8 in time: on the simulated four-post sweep, the force the WFS does not see
(F_contact - F_WFS) is the inertia of the mass below the sensor (m_wheel a_hub) where the
hub-acceleration compensation holds (its valid band reaches past 10 Hz)."""

from __future__ import annotations

import numpy as np

from bench.analysis.runs import force_difference_trace


def test_the_force_difference_follows_the_wheel_mass_times_the_hub_acceleration(
    four_post, four_post_analysis
):
    _, sweep = four_post
    _, result = four_post_analysis
    trace = force_difference_trace(sweep, result, around_hz=8.0, cycles=8)
    assert 8.0 <= trace.freq_hz <= 8.5  # where the sweep first reaches 8 Hz
    duration_s = trace.t_s[-1] - trace.t_s[0]
    assert 7.5 <= duration_s * trace.freq_hz <= 8.5  # eight periods
    rms = np.sqrt(np.mean(trace.inertial_n**2))
    # 2 mm at 8 Hz on the post: m_wheel (2 pi f)^2 z_hub of about a hundred newtons
    assert rms > 50
    # the compensation's ratio is within 10 % (magnitude) and 10 deg below 10 Hz: the residual of
    # the two traces, noise included, stays well under a fifth of the inertial force
    residual = np.sqrt(np.mean((trace.difference_n - trace.inertial_n) ** 2))
    assert residual < 0.2 * rms
    # and the difference is the whole inertial force: the raw WFS force misses it
    assert np.sqrt(np.mean(trace.difference_n**2)) > 0.8 * rms
