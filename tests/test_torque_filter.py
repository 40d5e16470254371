"""The notch and low-pass filters of the C library (csrc/include/pmsm2dof/filter.h) against their designs.

Truth from outside the C code:

- the designed filter: the continuous prototype of the issue (notch depth d at f0,
  -3 dB width W; low-pass 1/(2 zeta) at f0) mapped by SciPy's bilinear transform
  prewarped at f0, the notch's analog bandwidth found numerically (brentq) so that the
  discrete -3 dB band is W wide, not from the closed form the C code uses;
- the response of the C filter measured by driving ``p2d_filter_step`` with sinusoids
  until the transient has decayed (a least-squares fit of amplitude and phase);
- the anti-windup loop of the speed controller through the filters: the eigenvalues of
  its state matrix (NumPy) against the Routh test of ``p2d_speed_set_filter``;
- the torque command of the filtered speed controller against ``scipy.signal.lfilter``
  of the plain controller's command.
"""

import numpy as np
import pytest
from scipy import optimize, signal

from pmsm2dof._core import ffi, lib

PI = np.pi


def f32(x):
    return float(np.float32(x))


def filter_config(**fields):
    cfg = ffi.new("p2d_filter_config_t *")
    for name, value in fields.items():
        setattr(cfg, name, value)
    return cfg


def c_filter(Ts_s, **fields):
    f = ffi.new("p2d_filter_t *")
    status = lib.p2d_filter_init(f, filter_config(**fields), Ts_s)
    assert status == lib.P2D_OK, ffi.string(lib.p2d_status_param(status)).decode()
    return f


# --------------------------------------------------------------------------------------------
# designs, independent of the C code
# --------------------------------------------------------------------------------------------


def bilinear_prewarped(b_analog, a_analog, f0_Hz, Ts_s):
    """SciPy's bilinear transform with prewarping at f0 (the continuous and discrete responses agree at f0)."""
    w0 = 2 * PI * f0_Hz
    fs_warped = w0 / (2 * np.tan(w0 * Ts_s / 2))  # s = 2 fs_warped (z - 1)/(z + 1) = (w0 / g) (z - 1)/(z + 1)
    return signal.bilinear(b_analog, a_analog, fs=fs_warped)


def gain(ba, f_Hz, Ts_s):
    _, h = signal.freqz(*ba, worN=np.atleast_1d(2 * PI * np.asarray(f_Hz) * Ts_s))
    return np.abs(h)


def minus_3dB_band(ba, f0_Hz, Ts_s):
    """(f1, f2): the frequencies on either side of f0 where |H| = 1/sqrt(2)."""
    level = lambda f: gain(ba, f, Ts_s)[0] - np.sqrt(0.5)  # noqa: E731
    nyquist = 0.5 / Ts_s
    return (
        optimize.brentq(level, 1e-12 * nyquist, f0_Hz, xtol=1e-14 * nyquist),
        optimize.brentq(level, f0_Hz, nyquist * (1 - 1e-12), xtol=1e-14 * nyquist),
    )


def designed_notch(f0_Hz, width_Hz, depth, Ts_s):
    """(b, a) of the notch (s^2 + d B s + w0^2)/(s^2 + B s + w0^2), B solved for a discrete -3 dB width."""
    w0 = 2 * PI * f0_Hz

    def ba(B):
        return bilinear_prewarped([1.0, depth * B, w0**2], [1.0, B, w0**2], f0_Hz, Ts_s)

    def width_error(B):
        f1, f2 = minus_3dB_band(ba(B), f0_Hz, Ts_s)
        return (f2 - f1) - width_Hz

    B = optimize.brentq(width_error, 1e-6 * 2 * PI * width_Hz, 1e3 * 2 * PI * width_Hz, xtol=1e-12 * width_Hz)
    return ba(B)


def designed_lowpass(f0_Hz, zeta, Ts_s):
    w0 = 2 * PI * f0_Hz
    return bilinear_prewarped([w0**2], [1.0, 2 * zeta * w0, w0**2], f0_Hz, Ts_s)


def settling_samples(ba, time_constants=30):
    """Samples for the transient of the design (b, a) to decay by e^-time_constants."""
    radius = np.max(np.abs(np.roots(ba[1])))
    return int(np.ceil(time_constants / -np.log(radius)))


def measured_gain(f, f_Hz, Ts_s, n_settle, periods=40):
    """|H(f)| of the C filter: a sinusoid until the transient has decayed, then a least-squares fit."""
    lib.p2d_filter_reset(f, 0.0)
    out = ffi.new("p2d_filter_output_t *")
    n_fit = max(int(periods / (f_Hz * Ts_s)), 2000)
    k = np.arange(n_settle + n_fit)
    x = np.sin(2 * PI * f_Hz * Ts_s * k)
    y = np.empty(len(k))
    for i, xi in enumerate(x.astype(np.float32).tolist()):
        lib.p2d_filter_step(f, xi, out)
        y[i] = out.y
    tail = slice(n_settle, None)
    basis = np.stack([np.sin(2 * PI * f_Hz * Ts_s * k[tail]), np.cos(2 * PI * f_Hz * Ts_s * k[tail])], axis=1)
    coef, *_ = np.linalg.lstsq(basis, y[tail], rcond=None)
    return float(np.hypot(*coef))


NOTCHES = [  # f0 [Hz], width [Hz], depth, Ts [s]
    (50.0, 20.0, 0.1, 1e-3),  # a coupling resonance at a 1 kHz speed loop
    (300.0, 40.0, 0.0, 1e-3),  # near the Nyquist frequency, full depth
    (12.0, 2.0, 0.3, 1e-4),  # a slow belt resonance at 10 kHz: poles near z = 1
    pytest.param(2.0, 0.2, 0.05, 1e-4, marks=pytest.mark.slow),  # f0 Ts = 2e-4 (a long response: slow)
]


@pytest.mark.parametrize("f0, width, depth, Ts", NOTCHES)
def test_notch_equals_its_design(f0, width, depth, Ts):
    f = c_filter(Ts, notch_freq_Hz=f0, notch_width_Hz=width, notch_depth=depth)
    design = designed_notch(f0, width, depth, Ts)
    # the design has the properties
    assert gain(design, f0, Ts)[0] == pytest.approx(depth, abs=1e-9)
    f1, f2 = minus_3dB_band(design, f0, Ts)
    assert f2 - f1 == pytest.approx(width, rel=1e-9)
    # the C filter, measured: depth at f0, -3 dB at the band edges, unity far from it
    settle = settling_samples(design)
    assert measured_gain(f, f0, Ts, settle) == pytest.approx(depth, abs=2e-4)
    for edge in (f1, f2):
        assert measured_gain(f, edge, Ts, settle) == pytest.approx(np.sqrt(0.5), abs=2e-4)
    for other in (f0 / 20, min(f0 * 6, 0.45 / Ts)):
        assert measured_gain(f, other, Ts, settle) == pytest.approx(gain(design, other, Ts)[0], abs=2e-4)


LOWPASSES = [(200.0, 0.70710678, 1e-3), (450.0, 0.3, 1e-3), (5.0, 1.0, 1e-4)]


@pytest.mark.parametrize("f0, zeta, Ts", LOWPASSES)
def test_lowpass_equals_its_design(f0, zeta, Ts):
    f = c_filter(Ts, lowpass_freq_Hz=f0, lowpass_zeta=zeta)
    design = designed_lowpass(f0, zeta, Ts)
    assert gain(design, f0, Ts)[0] == pytest.approx(1 / (2 * zeta), rel=1e-9)
    settle = settling_samples(design)
    for freq in (f0 / 10, f0, min(2 * f0, 0.45 / Ts)):
        assert measured_gain(f, freq, Ts, settle) == pytest.approx(gain(design, freq, Ts)[0], abs=2e-4)


@pytest.mark.parametrize("f0_Ts", [1e-4, 1e-3])
def test_step_settles_where_a_float32_direct_form_does_not(f0_Ts):
    """The reason for the realization (filter.h): after a step, a low-pass near z = 1 run as a float32
    direct form (DF2T, NumPy float32) settles far from the step (its coefficients lose the DC gain); the
    C filter settles within its dead band, ulp(x) / (2 g k), where the increments of its states round away."""
    Ts = 1e-4
    f0, zeta = f0_Ts / Ts, 0.70710678
    b, a = (v.astype(np.float32) for v in designed_lowpass(f0, zeta, Ts))
    x = np.float32(0.731)
    n = int(40 / (2 * PI * f0 * Ts * zeta))  # 40 time constants
    s1 = s2 = np.float32(0.0)
    for _ in range(n):
        y = b[0] * x + s1
        s1 = b[1] * x - a[1] * y + s2
        s2 = b[2] * x - a[2] * y
    direct_error = abs(float(y) - float(x)) / float(x)
    f = c_filter(Ts, lowpass_freq_Hz=f0, lowpass_zeta=zeta)
    out = ffi.new("p2d_filter_output_t *")
    for _ in range(n):
        lib.p2d_filter_step(f, float(x), out)
    c = f.coef[0].lowpass
    dead_band = float(np.spacing(x)) / (2 * c.g * c.k)
    assert abs(out.y - float(x)) <= dead_band
    assert direct_error > 100 * dead_band / float(x)


# --------------------------------------------------------------------------------------------
# the speed controller's torque filters
# --------------------------------------------------------------------------------------------


def speed_config(**changes):
    J, alpha, zeta = 0.4, 20.0, 0.7
    cfg = dict(
        J_kgm2=J,
        alpha_radps=alpha,
        zeta=zeta,
        m=1.0,
        tau_i_s=0.0,
        Ka=1 / (J * alpha),
        Ts_s=1e-3,
        i_max_A=7.6,
        psi_f_Wb=0.35,
        Ld_H=12e-3,
        Lq_H=12e-3,
        pole_pairs=4,
        method=lib.P2D_TUSTIN,
        feedforward=lib.P2D_FF_LOWPASS,
        anti_windup=lib.P2D_AW_BACK_CALCULATION,
    )
    cfg.update(changes)
    return cfg


def speed_controller(filter_fields=None, **changes):
    ctl = ffi.new("p2d_speed_t *")
    assert lib.p2d_speed_init(ctl, ffi.new("p2d_speed_config_t *", speed_config(**changes))) == lib.P2D_OK
    status = lib.P2D_OK
    if filter_fields:
        status = lib.p2d_speed_set_filter(ctl, filter_config(**filter_fields))
    return ctl, status


def test_speed_command_is_the_plain_command_through_the_designed_filters():
    fields = dict(
        notch_freq_Hz=40.0, notch_width_Hz=15.0, notch_depth=0.05, lowpass_freq_Hz=200.0, lowpass_zeta=0.70710678
    )
    plain, _ = speed_controller()
    ctl, status = speed_controller(fields)
    assert status == lib.P2D_OK
    rng = np.random.default_rng(7)
    n = 2000
    w_ref = np.repeat(rng.uniform(-3, 3, 8), n // 8).astype(np.float32)
    w_m = 0.9 * w_ref + 0.2 * np.sin(2 * PI * 40.0 * 1e-3 * np.arange(n)) + 0.02 * rng.standard_normal(n)
    u, u_f = np.empty(n), np.empty(n)
    out = ffi.new("p2d_speed_output_t *")
    for k, (r, w) in enumerate(zip(w_ref.tolist(), w_m.astype(np.float32).tolist())):
        lib.p2d_speed_step(plain, r, w, out)
        assert not out.saturated
        u[k] = out.T_unsat_Nm
        lib.p2d_speed_step(ctl, r, w, out)
        assert not out.saturated and out.T_ref_Nm == out.T_unsat_Nm
        u_f[k] = out.T_unsat_Nm
    notch = designed_notch(40.0, 15.0, 0.05, 1e-3)
    lowpass = designed_lowpass(200.0, 0.70710678, 1e-3)
    expected = signal.lfilter(*lowpass, signal.lfilter(*notch, u))
    assert np.max(np.abs(u_f - expected)) <= 2e-6 * np.max(np.abs(expected))


def realized_state_space(coef):
    """(A, B, C, D) of the chain in double from its float32 coefficients and the equations of filter.h."""
    sections = []
    if coef.has_notch:
        sections.append((coef.notch, True))
    if coef.has_lowpass:
        sections.append((coef.lowpass, False))
    n = 2 * len(sections)
    A, B, C, D = np.zeros((n, n)), np.zeros(n), np.zeros(n), 1.0
    for i, (s, notch) in enumerate(sections):
        g, k, gh, c = s.g, s.k, s.g_h, s.c_band
        # v1 = s1 + gh (x - s2 - g s1 - k s1),  v2 = s2 + g v1, as rows over (s1, s2, x)
        v1 = np.array([1 - gh * (g + k), -gh, gh])
        v2 = np.array([0.0, 1.0, 0.0]) + g * v1
        y = np.array([0.0, 0.0, 1.0]) + c * v1 if notch else v2
        s1n, s2n = 2 * v1 - [1, 0, 0], 2 * v2 - [0, 1, 0]
        # the section's input is the chain's output so far: x = C_prev s + D_prev u
        j = slice(2 * i, 2 * i + 2)
        for row, new in ((2 * i, s1n), (2 * i + 1, s2n)):
            A[row] += new[2] * C
            A[row, j] += new[:2]
            B[row] = new[2] * D
        C, D = y[2] * C, y[2] * D
        C[j] += y[:2]
    return A, B, C, D


def test_anti_windup_loop_stability_agrees_with_the_eigenvalues():
    """x[k] = x[k-1] - g y[k], y = H(z) x[k-1]: stable iff the state matrix has its eigenvalues inside
    the unit circle; p2d_speed_set_filter accepts exactly those (cases within 1e-6 of the circle skipped)."""
    rng = np.random.default_rng(16)
    J, alpha, zeta, Ts = 0.4, 20.0, 0.7, 1e-3
    Ki = J * (alpha / (2 * zeta)) ** 2
    verdicts = {True: 0, False: 0}
    for _ in range(300):
        fields = {}
        if rng.uniform() < 0.7:
            fields.update(
                notch_freq_Hz=f32(10 ** rng.uniform(0, 2.6)),
                notch_width_Hz=f32(10 ** rng.uniform(-0.5, 2)),
                notch_depth=f32(rng.uniform(0, 0.7)),
            )
        if not fields or rng.uniform() < 0.6:
            fields.update(
                lowpass_freq_Hz=f32(10 ** rng.uniform(0, 2.6)), lowpass_zeta=f32(10 ** rng.uniform(-1.5, 0.5))
            )
        fields = {k: v for k, v in fields.items() if not (k.endswith("_Hz") and v >= 0.49 / Ts)}
        if not any(k.endswith("freq_Hz") for k in fields):
            continue
        ctl, status = speed_controller(dict(fields), Ka=1e-9)  # Ki Ka Ts = 1e-9: stable through any filter
        assert status == lib.P2D_OK, fields
        A, B, C, D = realized_state_space(ctl.filter_coef[ctl.active])
        Ka = f32(10 ** rng.uniform(-3, np.log10(1.99)) / (Ki * Ts))  # Ki Ka Ts < 2 is checked on its own
        status = lib.p2d_speed_set_config(ctl, ffi.new("p2d_speed_config_t *", speed_config(Ka=Ka)))
        assert status in (lib.P2D_OK, lib.P2D_ERR_KA)
        # Ki Ka Ts as the C library rounds it (eq 9 in float32)
        Ki32 = np.float32(J) * (np.float32(alpha) / (np.float32(2) * np.float32(zeta))) ** 2
        g = float(Ki32 * np.float32(Ka) * np.float32(Ts))
        M = np.block([[np.array([[1 - g * D]]), -g * C[None, :]], [B[:, None], A]])
        rho = np.max(np.abs(np.linalg.eigvals(M)))
        if abs(rho - 1) < 1e-6:
            continue
        assert (status == lib.P2D_OK) == (rho < 1), (fields, g, rho, status)
        verdicts[rho < 1] += 1
    assert verdicts[True] > 50 and verdicts[False] > 50, verdicts
