"""Write the seed corpus of the fuzz targets (csrc/fuzz/corpus/<target>, one folder per target).

Each seed is a byte string in the input format decoded by fuzz_common.h and the
fuzz_<target>.c of each target of main(): a configuration, then operations. The seeds
start the fuzzer from meaningful runs (the paper's drive in closed loop, a
stall beyond the current limit, torque filters on a saturating drive, parameter
updates valid and invalid, NaN and inf inputs, odd applied commands, a resonant
filter driven into overflow) instead of from empty inputs.

Run from the repository root after changing the input format:

    python3 csrc/fuzz/make_seeds.py
"""

import base64
import math
import struct
from pathlib import Path

CORPUS = Path(__file__).resolve().parent / "corpus"

# float tags of fuzz_common.h
RAW, SPECIAL, NEAR = 0, 1, 2
SPECIAL_INDEX = {"0": 0, "-0": 1, "nan": 2, "-nan": 3, "inf": 4, "-inf": 5, "max": 6, "-max": 7}

# operations (op % 8) of the speed and current targets; SET_FILTER (speed target only)
SAMPLE, SET_FILTER, CLOSED_LOOP, SET_MUTATED, SET_FRESH, RESET = 0, 3, 4, 5, 6, 7
# operations (op % 4) of the filter target; bit 2 of FILTER_SET: one field redrawn
FILTER_STEP, FILTER_RUN, FILTER_SET, FILTER_RESET = 0, 1, 2, 3


def nominal(factor=1.0):
    """A float equal to the nominal value of its field times ``factor`` (tag 2, within two decades)."""
    k = round(16384 * math.log10(abs(factor)))
    if not -32768 <= k <= 32767:
        raise ValueError(f"factor {factor} is beyond two decades")
    bits = (k & 0xFFFF) | (0x10000 if factor < 0 else 0)
    return struct.pack("<BI", NEAR, bits)


def special(name):
    """One of the special values of FZ_SPECIAL."""
    return struct.pack("<BI", SPECIAL, SPECIAL_INDEX[name])


def raw(x):
    """The float32 nearest to x, as a raw bit pattern."""
    return struct.pack("<B", RAW) + struct.pack("<f", x)


def u8(v):
    return struct.pack("<B", v)


def u16(v):
    return struct.pack("<H", v)


def fraction(f):
    """A fraction in [0, 1] (fz_unit)."""
    return u16(round(f * 65535))


def speed_config(
    surface=True, m=None, method=2, feedforward=1, anti_windup=1, J=nominal(), Ts=nominal(), zeta=nominal()
):
    """Speed controller configuration; m None means m = 1 (shape bit 1)."""
    shape = (1 if surface else 0) | (2 if m is None else 0)
    out = u8(shape) + J + nominal() + zeta  # J, alpha, zeta
    if m is not None:
        out += m
    out += nominal() + nominal() + Ts + nominal() + nominal() + nominal()  # tau_i, Ka, Ts, i_max, psi_f, Ld
    if not surface:
        out += nominal()  # Lq = 0.02 H against Ld = 0.01 H
    return out + u8(3) + u8(method) + u8(feedforward) + u8(anti_windup)  # pole pairs 1 + 3 = 4


def speed_sample(w_ref, w_m, mode=0, frac=1.0, applied=b""):
    return u8(SAMPLE + 8 * mode) + w_ref + w_m + fraction(frac) + applied


def speed_closed_loop(n, w_ref, T_load, mode=0, frac=1.0, J_mismatch=0.5):
    return u8(CLOSED_LOOP) + u16(n - 1) + w_ref + T_load + u8(mode) + fraction(frac) + fraction(J_mismatch)


def filter_config(notch=True, lowpass=True, notch_fields=None, lowpass_fields=None):
    """Torque or standalone filter configuration (fuzz_speed.c, fuzz_filter.c): shape bits 0 (notch), 1 (low-pass)."""
    out = u8((1 if notch else 0) | (2 if lowpass else 0))
    if notch:
        out += b"".join(notch_fields or (nominal(), nominal(), nominal()))  # f0, width, depth
    if lowpass:
        out += b"".join(lowpass_fields or (nominal(), nominal()))  # f0, zeta
    return out


def filter_run(n, amplitude, offset, cycles_per_sample):
    """A sinusoid of n samples, cycles_per_sample in [0, 0.5] (fuzz_filter.c)."""
    return u8(FILTER_RUN) + u16(n - 1) + amplitude + offset + fraction(2 * cycles_per_sample)


def current_config(surface=False, decouple=True, method=2, anti_windup=1, Rs=nominal(), tau_i=nominal()):
    """Current controller configuration; tau_i is relative to its nominal value 10 Ts."""
    shape = (1 if surface else 0) | (2 if decouple else 0)
    out = u8(shape) + Rs + nominal()  # Rs, Ld
    if not surface:
        out += nominal()  # Lq
    return out + nominal() + nominal() + tau_i + u8(method) + u8(anti_windup)  # psi_f, Ts, tau_i


def current_inputs(id_ref, iq_ref, id_, iq, w_e, u_dc):
    return id_ref + iq_ref + id_ + iq + w_e + u_dc


def current_sample(inputs, mode=0, frac=1.0, angle=0.0, applied=b""):
    return u8(SAMPLE + 8 * mode) + inputs + fraction(frac) + fraction(angle) + applied


def current_closed_loop(n, inputs, mode=0, frac=1.0, angle=0.0, mismatch=0.5):
    return u8(CLOSED_LOOP) + u16(n - 1) + u8(mode) + fraction(frac) + fraction(angle) + fraction(mismatch) + inputs


SPEED_SEEDS = {
    # the paper's drive (J = 0.4 kg m^2, i_max = 7.6 A): Tustin, lowpass, back calculation;
    # a step to 100 rad/s under 1 Nm, then to -50 rad/s
    "paper_tustin_lowpass_backcalc": speed_config()
    + speed_closed_loop(2048, nominal(), nominal())
    + speed_closed_loop(1500, nominal(-0.5), nominal()),
    # salient PMSM, backward Euler, full feedforward, clamping: a load 30x nominal stalls the drive,
    # then the load drops
    "salient_full_clamping_stall": speed_config(surface=False, method=1, feedforward=3, anti_windup=2)
    + speed_closed_loop(1000, nominal(), nominal(30.0))
    + speed_closed_loop(2000, nominal(), nominal(0.01)),
    # forward Euler, no_tau with m = 2, no anti-windup; non-finite and huge inputs
    "forward_notau_nan_inputs": speed_config(m=nominal(2.0), method=0, feedforward=2, anti_windup=0)
    + speed_sample(nominal(), nominal(0.5))
    + speed_sample(nominal(), special("nan"))
    + speed_sample(special("inf"), nominal())
    + speed_sample(special("-max"), special("max"))
    + speed_sample(raw(3e38), raw(-3e38))
    + speed_sample(nominal(), nominal(0.9)),
    # parameter updates mid-run: alpha x2 (valid), Ts NaN (refused), fresh invalid config, feedforward none
    "set_config_mid_run": speed_config()
    + speed_closed_loop(300, nominal(), nominal())
    + u8(SET_MUTATED)
    + u8(1)
    + nominal(2.0)
    + speed_closed_loop(300, nominal(), nominal())
    + u8(SET_MUTATED)
    + u8(6)
    + special("nan")
    + u8(SET_FRESH)
    + speed_config(J=raw(-1.0))
    + u8(SET_MUTATED)
    + u8(13)
    + u8(0)
    + speed_closed_loop(300, nominal(), nominal()),
    # bumpless reset to finite, non-finite and overflowing points
    "reset_points": speed_config(surface=False, method=1, feedforward=3)
    + u8(RESET)
    + nominal()
    + nominal()
    + speed_sample(nominal(), nominal())
    + u8(RESET)
    + special("nan")
    + nominal()
    + u8(RESET)
    + raw(3e38)
    + raw(-3e38)
    + speed_sample(nominal(), nominal()),
    # applied torque: scaled, any within the limit, NaN, huge
    "applied_torque_modes": speed_config(anti_windup=2)
    + speed_sample(nominal(), nominal(0.01), mode=1, frac=0.3)
    + speed_sample(nominal(), nominal(0.01), mode=2, frac=0.9)
    + speed_sample(nominal(), nominal(0.01), mode=3, applied=special("nan"))
    + speed_sample(nominal(), nominal(0.01), mode=3, applied=raw(1e30))
    + speed_closed_loop(500, nominal(), nominal(5.0), mode=2, frac=0.1),
    # a configuration init rejects (J < 0)
    "rejected_init": speed_config(J=raw(-0.4)),
}

SPEED_SEEDS.update(
    {
        # the paper's drive with a notch at 40 Hz and a low-pass at 200 Hz: steps that saturate, then back
        "filtered_paper_drive_saturating": speed_config()
        + u8(SET_FILTER)
        + filter_config()
        + speed_closed_loop(2048, nominal(30.0), nominal())
        + speed_closed_loop(1500, nominal(-0.5), nominal()),
        # salient PMSM, clamping, notch only: applied torques scaled and arbitrary
        "filtered_salient_clamping": speed_config(surface=False, anti_windup=2)
        + u8(SET_FILTER)
        + filter_config(lowpass=False)
        + speed_closed_loop(800, nominal(20.0), nominal(5.0), mode=1, frac=0.5)
        + speed_sample(nominal(), nominal(0.01), mode=3, applied=special("nan"))
        + speed_closed_loop(800, nominal(), nominal(), mode=2, frac=0.2),
        # filter updates: an invalid depth, the low-pass alone, none, a Ts that puts the low-pass above Nyquist
        "set_filter_switching": speed_config()
        + u8(SET_FILTER)
        + filter_config(notch_fields=(nominal(), nominal(), nominal(20.0)))
        + u8(SET_FILTER)
        + filter_config(notch=False)
        + speed_closed_loop(300, nominal(), nominal())
        + u8(SET_FILTER)
        + filter_config(notch=False, lowpass=False)
        + speed_closed_loop(300, nominal(), nominal())
        + u8(SET_FILTER)
        + filter_config()
        + u8(SET_MUTATED)
        + u8(6)
        + nominal(10.0)
        + u8(RESET)
        + nominal()
        + nominal()
        + speed_closed_loop(300, nominal(), nominal()),
    }
)

# fuzz_filter.c: Ts, then the configuration (nominal: notch 50 Hz, 20 Hz wide, depth 0.1; low-pass 300 Hz, zeta 0.7)
FILTER_SEEDS = {
    # both sections at 1 kHz: sinusoids at the notch, at the low-pass and near Nyquist, a step
    "notch_lowpass_sines": nominal()
    + filter_config()
    + filter_run(2048, nominal(), nominal(0.5), 0.05)
    + filter_run(1000, nominal(3.0), nominal(-1.0), 0.3)
    + filter_run(500, nominal(), nominal(), 0.49)
    + filter_run(500, nominal(0.01), nominal(2.0), 0.0),
    # a narrow notch near z = 1: 2 Hz, 0.2 Hz wide, at 10 kHz
    "narrow_notch_10kHz": nominal(0.1)
    + filter_config(lowpass=False, notch_fields=(nominal(0.04), nominal(0.01), nominal(0.5)))
    + filter_run(2048, nominal(), nominal(), 2e-4)
    + u8(FILTER_RESET)
    + nominal(7.0)
    + filter_run(2048, nominal(), nominal(7.0), 1e-3),
    # a resonant low-pass (zeta = 0.01) driven at f0 at 3e38: its states overflow before its output; recovery
    "resonant_lowpass_overflow": nominal()
    + filter_config(notch=False, lowpass_fields=(nominal(), nominal(1 / 70)))
    + filter_run(2048, raw(3e38), nominal(), 0.3)
    + u8(FILTER_RESET)
    + special("nan")
    + filter_run(100, nominal(), nominal(), 0.3),
    # updates: a field redrawn, the notch off, a fresh invalid configuration, a low-pass above Nyquist
    "set_config_switching": nominal()
    + filter_config(notch=False)
    + filter_run(300, nominal(), nominal(4.0), 0.01)
    + u8(FILTER_SET)
    + filter_config()
    + u8(FILTER_SET | 4)
    + u8(1)
    + nominal(3.0)
    + u8(FILTER_SET | 4)
    + u8(5)
    + u8(FILTER_SET)
    + filter_config(notch_fields=(nominal(), nominal(), raw(0.9)))
    + u8(FILTER_SET | 4)
    + u8(3)
    + nominal(2.0)
    + filter_run(300, nominal(), nominal(), 0.1),
    # non-finite and huge samples, resets
    "non_finite_samples": nominal()
    + filter_config()
    + u8(FILTER_STEP)
    + special("nan")
    + u8(FILTER_STEP)
    + special("inf")
    + u8(FILTER_STEP)
    + raw(3e38)
    + u8(FILTER_RESET)
    + raw(-3e38)
    + u8(FILTER_STEP)
    + nominal(),
    # a sampling period init rejects
    "rejected_init": raw(-1e-3) + filter_config(),
}

CURRENT_SEEDS = {
    # salient motor, decoupled dq PIs, Tustin, back calculation: a closed-loop current step at 400 rad/s
    "salient_tustin_backcalc": current_config()
    + current_closed_loop(2048, current_inputs(nominal(), nominal(), nominal(), nominal(), nominal(), nominal())),
    # a reference far beyond the DC link (voltage limit), then back
    "voltage_limit": current_config(anti_windup=2)
    + current_closed_loop(1000, current_inputs(nominal(), nominal(50.0), nominal(), nominal(), nominal(), nominal()))
    + current_closed_loop(1000, current_inputs(nominal(), nominal(), nominal(), nominal(), nominal(), nominal())),
    # surface motor, no decoupling, forward Euler, no anti-windup; non-finite inputs including u_dc
    "surface_forward_nan_inputs": current_config(surface=True, decouple=False, method=0, anti_windup=0)
    + current_sample(current_inputs(nominal(), nominal(), nominal(0.5), nominal(0.5), nominal(), nominal()))
    + current_sample(current_inputs(nominal(), nominal(), special("nan"), nominal(), nominal(), nominal()))
    + current_sample(current_inputs(nominal(), nominal(), nominal(), nominal(), special("inf"), nominal()))
    + current_sample(current_inputs(nominal(), nominal(), nominal(), nominal(), nominal(), special("nan")))
    + current_sample(current_inputs(nominal(), nominal(), nominal(), nominal(), nominal(), raw(-300.0)))
    + current_sample(current_inputs(raw(3e38), raw(-3e38), nominal(), nominal(), nominal(), raw(1e30))),
    # parameter updates: Ts x5 (valid), Rs NaN (refused), decoupling toggled, fresh invalid config
    "set_config_mid_run": current_config(method=1)
    + current_closed_loop(200, current_inputs(nominal(), nominal(), nominal(), nominal(), nominal(), nominal()))
    + u8(SET_MUTATED)
    + u8(5)
    + nominal(5.0)
    + u8(SET_MUTATED)
    + u8(0)
    + special("nan")
    + u8(SET_MUTATED)
    + u8(8)
    + u8(SET_FRESH)
    + current_config(Rs=raw(-0.5))
    + current_closed_loop(200, current_inputs(nominal(), nominal(), nominal(), nominal(), nominal(), nominal()))
    + u8(RESET),
    # applied voltage: scaled, any inside the circle, NaN, huge
    "applied_voltage_modes": current_config(anti_windup=2)
    + current_sample(
        current_inputs(nominal(), nominal(20.0), nominal(), nominal(), nominal(), nominal()), mode=1, frac=0.5
    )
    + current_sample(
        current_inputs(nominal(), nominal(20.0), nominal(), nominal(), nominal(), nominal()),
        mode=2,
        frac=0.99,
        angle=0.3,
    )
    + current_sample(
        current_inputs(nominal(), nominal(), nominal(), nominal(), nominal(), nominal()),
        mode=3,
        applied=special("nan") + nominal(),
    )
    + current_sample(
        current_inputs(nominal(), nominal(), nominal(), nominal(), nominal(), nominal()),
        mode=3,
        applied=raw(1e30) + raw(-1e30),
    ),
    # a configuration init rejects (tau_i = Ts / 2 < Ts)
    "rejected_init": current_config(tau_i=nominal(0.05)),
}


COMMISSION_FIELDS = (
    "Ts",
    "tau_i",
    "i_test",
    "i_spin",
    "i_trip",
    "t_align",
    "t_level",
    "t_inductance",
    "t_ramp",
    "t_spin",
    "w_e_spin",
)


def commission_config(delay=0, **fields):
    """Commissioning configuration (fuzz_commission.c): the two name bytes, then the fields in order, each
    nominal unless given (as a float of nominal(), special() or raw()), then voltage_delay_samples."""
    unknown = set(fields) - set(COMMISSION_FIELDS)
    if unknown:
        raise ValueError(f"no commissioning fields {sorted(unknown)}")
    return u8(3) + u8(2) + b"".join(fields.get(name, nominal()) for name in COMMISSION_FIELDS) + u8(delay)


def commission_closed_loop(
    n, R=0.5, Ld=0.5, Lq_ratio=0.5, psi_f=0.5, J=0.5, load=0.0, u_dc=0.5, inverted=False, delayed=False
):
    """A closed-loop run; the motor parameters as fractions (0.5: the nominal servo, 0 and 1: a factor 4 off)."""
    return (
        u8(CLOSED_LOOP)
        + u16(n - 1)
        + fraction(R)
        + fraction(Ld)
        + fraction(Lq_ratio)
        + fraction(psi_f)
        + fraction(J)
        + fraction(load)
        + fraction(u_dc)
        + u8((1 if inverted else 0) | (2 if delayed else 0))
    )


def commission_sample(id_, iq, u_dc):
    return u8(SAMPLE) + id_ + iq + u_dc


def commission_nonfinite(kind, which):
    """One sample with NaN, -NaN, inf or -inf (kind 0..3) in id, iq or u_dc (which 0..2)."""
    return u8(7) + u8(kind) + u8(which)


COMMISSION_SEEDS = {
    # the nominal servo (Lq = 2 Ld) commissioned to DONE, then steps after the end
    "nominal_to_done": commission_config() + commission_closed_loop(16384) + commission_closed_loop(64),
    # one period of computation delay, a surface motor (Lq = Ld), a heavier rotor
    "delay_surface": commission_config(delay=1) + commission_closed_loop(16384, Lq_ratio=0.0, J=1.0, delayed=True),
    # current sensing of the wrong sign: the loop runs away into i_trip_A
    "inverted_sensing": commission_config() + commission_closed_loop(4000, inverted=True),
    # a 20 A test on 12 V through 0.8 ohm: the current does not reach its level
    "current_not_reached": commission_config(i_test=nominal(10.0), i_trip=nominal(10.0))
    + commission_closed_loop(4000, u_dc=0.0),
    # no spin current to speak of (1.8e-40 A) and a short flux test (27 rad/s, averaged over 16 ms): the
    # rotor creeps on what the ramp left it while the frame turns, psi_a turns by too little over so short
    # a window to lose its coherence, and the drops it must exceed are nil: only the slip shows that the
    # tiny psi_f is wrong (found by the fuzzer)
    "creeping_rotor": commission_config(i_spin=raw(1.8e-40), t_ramp=raw(0.0155), t_spin=raw(0.0315), w_e_spin=raw(27.0))
    + commission_closed_loop(8192, J=0.5255, load=0.0078, u_dc=0.5255, delayed=True),
    # a light rotor (J 6.4e-5) with a small magnet after a fast ramp (15.5 ms to 67 rad/s) still swings about
    # the I-f frame through the flux test's window, 1.5 swings that end 0.6 rad from where they began: its mean
    # speed is 5.6 % below the frame's, |psi_a| and psi_f with it, while the window's halves look alike; the
    # angle psi_a turns by over the window measures that speed (found by the fuzzer)
    "swinging_light_rotor": commission_config(i_spin=raw(1.03795648), t_ramp=raw(0.0155), w_e_spin=raw(67.2036057))
    + commission_closed_loop(
        13557,
        R=0.0935679,
        Ld=0.0901950,
        Lq_ratio=0.0899527,
        psi_f=0.0901950,
        J=0.0901961,
        load=0.00816358,
        u_dc=0.00099049,
    ),
    # the most load and saliency: the rotor moves, or does not follow the I-f frame
    "loaded_salient": commission_config() + commission_closed_loop(16384, Lq_ratio=1.0, load=1.0),
    # NaN and inf inputs in the middle of a run, then the run goes on
    "nonfinite_mid_run": commission_config()
    + commission_closed_loop(700)
    + commission_nonfinite(0, 0)
    + commission_nonfinite(2, 1)
    + commission_nonfinite(3, 2)
    + commission_closed_loop(16384),
    # a restart mid-run, and a fresh configuration
    "restart": commission_config()
    + commission_closed_loop(1500)
    + u8(6)
    + commission_closed_loop(3000)
    + u8(5)
    + commission_config(Ts=nominal(0.5))
    + commission_closed_loop(3000),
    # single samples with odd values: huge currents (the trip), a negative and a zero DC link
    "odd_samples": commission_config()
    + commission_sample(nominal(), nominal(), nominal())
    + commission_sample(nominal(0.1), nominal(), raw(-48.0))
    + commission_sample(nominal(), nominal(), special("0"))
    + commission_sample(raw(3e38), raw(-3e38), nominal()),
    # a configuration init rejects (i_trip below 1.5 i_test)
    "rejected_init": commission_config(i_trip=raw(1.0)),
}


def encoder_config(estimator=1, lowpass=True, cpr=10000, bits_byte=0, Ts=nominal()):
    """Encoder configuration: cpr counts per revolution (1..65536); bits_byte 0 (16 bits), 1 (32 bits), or b
    with b % 3 == 2 (2 + b % 31 bits); PLL (estimator 1) or difference (0); low-pass at its nominal 300 rad/s
    or none."""
    return (
        u8(0 if lowpass else 1)
        + u8(0)
        + u16(cpr - 1)
        + u8(bits_byte)
        + Ts
        + u8(estimator)
        + nominal()
        + (nominal() if lowpass else b"")
    )


def encoder_steps(increments):
    """Readings of the previous one plus each signed increment (op 0)."""
    return b"".join(u8(0) + struct.pack("<h", d) for d in increments)


def encoder_trajectory(n, w_end):
    return u8(CLOSED_LOOP) + u16(n - 1) + w_end


def fw_config(method=2, anti_windup=1, Ka=nominal(), id_min=nominal()):
    """Field-weakening configuration (Kp, Ki, Ka, Ts, voltage_ratio, id_min at their nominal values)."""
    return nominal() + nominal() + Ka + nominal() + nominal() + id_min + u8(method) + u8(anti_windup)


def fw_speed_config(shape=0):
    """Speed controller of the field-weakening target; shape % 3: surface, Ld < Lq, Ld > Lq; shape // 3 % 3: AW."""
    return u8(shape) + nominal() + nominal() + nominal() + nominal() + nominal()  # J, alpha, i_max, psi_f, Ld


def fw_sample(ud, uq, u_dc):
    return u8(SAMPLE) + ud + uq + u_dc


def fw_speed_sample(w_ref, w_m, id_fw, mode=0, applied=b""):
    return u8(3 + 8 * mode) + w_ref + w_m + id_fw + applied


def fw_closed_run(n, w_e, w_ref=nominal(), u_dc=nominal()):
    return u8(CLOSED_LOOP) + u16(n - 1) + w_e + w_ref + u_dc


ENCODER_SEEDS = {
    # 10000 counts/rev, 16-bit timer, PLL at 200 rad/s with a low-pass: a ramp to 100 rad/s, then to -150 rad/s
    "pll_lowpass_ramps": encoder_config()
    + encoder_trajectory(2048, nominal())
    + encoder_trajectory(2048, nominal(-1.5)),
    # difference estimator on a 32-bit counter: increments across the wrap, the largest ones
    "difference_32bit_wrap": encoder_config(estimator=0, lowpass=False, bits_byte=1)
    + u8(7)
    + struct.pack("<I", 0xFFFFFF00)
    + nominal()
    + encoder_steps([300, 300, -1000, 32767, -32768, 0, 1])
    + u8(3)
    + struct.pack("<I", 0x7FFFFFFF)
    + u8(3)
    + struct.pack("<I", 0xFFFFFFFF),
    # a 12-bit counter, PLL without filter, a deadbeat bandwidth (w Ts = 2) then a slow one, then the difference
    "pll_12bit_bandwidth_changes": encoder_config(lowpass=False, bits_byte=41, cpr=8192)
    + encoder_trajectory(500, nominal(1.2))
    + u8(SET_MUTATED)
    + u8(4)
    + nominal(10.0)
    + encoder_trajectory(500, nominal(0.3))
    + u8(SET_MUTATED)
    + u8(4)
    + nominal(0.01)
    + encoder_trajectory(500, nominal(-0.3))
    + u8(SET_MUTATED)
    + u8(3)
    + u8(0)
    + encoder_trajectory(300, nominal()),
    # resets at finite, NaN and overflowing speeds; a rejected fresh configuration (Ts NaN)
    "resets_and_rejections": encoder_config()
    + u8(RESET)
    + struct.pack("<I", 40000)
    + nominal()
    + encoder_steps([159, 159, 160])
    + u8(RESET)
    + struct.pack("<I", 3)
    + special("nan")
    + u8(RESET)
    + struct.pack("<I", 3)
    + raw(3e38)
    + u8(SET_FRESH)
    + encoder_config(Ts=special("nan"))
    + encoder_steps([5, -5]),
    # a configuration init rejects (bandwidth w Ts = 10 > 2)
    "rejected_init": u8(0) + u8(0) + u16(9999) + u8(0) + nominal() + u8(1) + nominal(50.0) + nominal(),
}

FIELD_WEAKENING_SEEDS = {
    # found by the fuzzer: a subnormal torque reference (2.8e-44 Nm) on a current circle of 1.1e-19 A, where
    # one rounding of iq moves the torque it gives by 1 % (the torque invariant holds away from subnormals)
    "subnormal_torque_on_the_circle": base64.b64decode(
        "AgAAAAACAAAAAAIAAAAAAgAAAAACAAAIAAIAvLy8vLy8vLwAAAACAAAAAAABAAAgAAAAABb//xUAAHwCAP7//////wECAAAAAgAA"
        "AAD+///////9+wAAAAIAAAAAAQQAAAQAAOx4rWAA7HitYAIAAAAAAAIAAAAAAgAAAAACAAABAAcCAAEEAAAEAADseK1gAOx4rWAC"
        "AAAAAAACAAAAAAIAAAAAAgAAAQAHAkQTAQACAAAAAAIAAAAABwECAAAAAgAAAAACAAAAAAUBAgTPBwIAAAAAAgAAAAACAAAAAATP"
        "BwKIJgAAAgAAAAACAAAAAAQAAAAA"
    ),
    # surface PMSM of a 48 V servo, Tustin back calculation: above base speed, then far above (id at id_min), back
    "surface_backcalc_speed_sweep": fw_config()
    + fw_speed_config(3)
    + fw_closed_run(2000, nominal())
    + fw_closed_run(2000, nominal(4.0))
    + fw_closed_run(2000, nominal(0.2)),
    # salient (Ld < Lq), clamping: field-weakening entry with ids inside, at and beyond -i_max, positive, NaN
    "salient_clamping_entry": fw_config(anti_windup=2)
    + fw_speed_config(1 + 3 * 2)
    + fw_closed_run(1000, nominal(1.5))
    + fw_speed_sample(nominal(), nominal(0.1), nominal(-0.5))
    + fw_speed_sample(nominal(10.0), nominal(0.1), nominal(-3.0))
    + fw_speed_sample(nominal(10.0), nominal(0.1), nominal(-1.5), mode=1, applied=fraction(0.5))
    + fw_speed_sample(nominal(), nominal(0.1), nominal(0.5), mode=2, applied=special("nan"))
    + fw_speed_sample(nominal(), nominal(0.1), special("nan")),
    # Ld > Lq: the bound id <= id_fw overrides the positive MTPA current
    "reverse_saliency": fw_config(method=1)
    + fw_speed_config(2)
    + fw_closed_run(1500, nominal(2.0))
    + fw_speed_sample(nominal(10.0), nominal(0.1), nominal(-2.9)),
    # non-finite and overflowing voltages, negative DC link, resets, parameter updates valid and not
    "faults_and_updates": fw_config(method=0, anti_windup=1)
    + fw_speed_config(0)
    + fw_sample(nominal(), nominal(), nominal())
    + fw_sample(special("nan"), nominal(), nominal())
    + fw_sample(nominal(), nominal(), special("inf"))
    + fw_sample(raw(1e20), raw(1e20), nominal())
    + fw_sample(nominal(), nominal(), nominal(-1.0))
    + u8(RESET)
    + nominal(-2.0)
    + nominal()
    + nominal()
    + u8(RESET)
    + special("nan")
    + nominal()
    + nominal()
    + u8(SET_MUTATED)
    + u8(1)
    + nominal(5.0)
    + u8(SET_MUTATED)
    + u8(4)
    + nominal(2.0)
    + u8(SET_FRESH)
    + fw_config(Ka=nominal(10.0))
    + fw_closed_run(500, nominal(3.0)),
    # a configuration init rejects (id_min > 0)
    "rejected_init": fw_config(id_min=nominal(-1.0)) + fw_speed_config(0),
}


def inertia_config(period_mean=False, J0=nominal(), J_min=nominal(), J_max=nominal(), J_memory=nominal()):
    """Inertia estimator configuration around J0 = 0.01 kg m^2 (fuzz_inertia.c)."""
    out = u8(1 if period_mean else 0) + nominal() + J0 + J_min + J_max  # Ts, J0, J_min, J_max
    out += nominal() + nominal() + nominal() + J_memory  # B_max, T_load_max, sigma_T, J_memory
    return out + nominal() + nominal() + nominal()  # load_memory, w_f, J_rel_sd_max


def inertia_closed_loop(
    n,
    J=0.5,
    B=0.5,
    T_load=nominal(),
    w_amp=nominal(),
    T_max=nominal(),
    alpha=0.4,
    noise=0.0,
    encoder=False,
    half_period=250,
):
    """A closed-loop run; J is the fraction of the range J0/30 .. 30 J0 (0.5: J0)."""
    return (
        u8(CLOSED_LOOP)
        + u16(n - 1)
        + fraction(J)
        + fraction(B)
        + T_load
        + w_amp
        + T_max
        + fraction(alpha)
        + fraction(noise)
        + u8(1 if encoder else 0)
        + u16(half_period - 1)
    )


def inertia_sample(w_m, T_e):
    return u8(SAMPLE) + w_m + T_e


INERTIA_SEEDS = {
    # a servo at 1 kHz under a square-wave speed reference, J = J0, then J = 3 J0 with torque noise
    "servo_closed_loop": inertia_config() + inertia_closed_loop(2048) + inertia_closed_loop(2048, J=0.66, noise=0.5),
    # an encoder of 16384 counts per turn, speed as the period mean
    "encoder_period_mean": inertia_config(period_mean=True)
    + inertia_closed_loop(2048, encoder=True, noise=0.3)
    + inertia_closed_loop(2048, J=0.3, encoder=True),
    # the drive at rest for 3 x 2048 samples with a J memory of 0.1 s: J is never excited
    "low_excitation": inertia_config(J_memory=nominal(0.01))
    + inertia_closed_loop(2048, T_load=raw(0.0), w_amp=raw(1e-4), half_period=1000)
    + inertia_closed_loop(2048, T_load=raw(0.0), w_amp=raw(1e-4), half_period=1000)
    + inertia_closed_loop(2048, T_load=raw(0.0), w_amp=raw(1e-4), half_period=1000),
    # a drive 30 times heavier than J0 with J_max = J0, after a NaN, an inf and an overflow
    "beyond_J_max": inertia_config(J_max=nominal(0.1))
    + inertia_closed_loop(2048, J=1.0, T_max=nominal(20.0))
    + inertia_sample(special("nan"), nominal())
    + inertia_sample(nominal(), special("-inf"))
    + inertia_sample(raw(3e38), nominal())
    + inertia_closed_loop(1000, J=1.0, T_max=nominal(20.0)),
    # non-finite and huge inputs, between samples of a drive
    "nan_inputs": inertia_config()
    + inertia_closed_loop(300)
    + inertia_sample(special("nan"), nominal())
    + inertia_sample(nominal(), special("inf"))
    + inertia_sample(special("max"), special("-max"))
    + inertia_sample(raw(3e38), raw(-3e38))
    + inertia_closed_loop(300),
    # parameter updates mid-run: J memory x0.1 (valid), J0 NaN (refused), a fresh invalid config,
    # the speed pairing toggled, reset keeping the estimate, reset to the prior
    "set_config_mid_run": inertia_config()
    + inertia_closed_loop(500)
    + u8(SET_MUTATED)
    + u8(7)
    + nominal(0.1)
    + inertia_closed_loop(500)
    + u8(SET_MUTATED)
    + u8(1)
    + special("nan")
    + u8(SET_FRESH)
    + inertia_config(J_min=raw(0.1))
    + u8(SET_MUTATED)
    + u8(11)
    + u8(RESET)
    + u8(1)
    + inertia_closed_loop(500)
    + u8(RESET)
    + u8(0)
    + inertia_closed_loop(500),
    # a configuration init rejects (J_min = 1 kg m^2 > J0)
    "rejected_init": inertia_config(J_min=raw(1.0)),
}

# operations (op % 8) of the XCP target (fuzz_xcp.c)
XCP_CMD, XCP_CMD_NEAR, XCP_STREAM, XCP_EVENT, XCP_CALIBRATE, XCP_TAKE, XCP_CLOCK = 0, 2, 3, 4, 5, 6, 7


def xcp_config(cto=247, dto=100, queue=255, daq=255, options=0, seed=3):
    """max_cto = 8 + cto % 248, max_dto = 8 + 2 dto, queue max_dto + 2 + 4 queue, DAQ memory 1 + 8 daq bytes;
    options: bit 0 calibration and bit 1 DAQ under seed and key, bit 2 an A2L name, bit 3 framing checksum."""
    return bytes([cto, dto, queue, daq, options, seed, 0, 0])


def xcp(*packet):
    """A command packet."""
    return u8(XCP_CMD) + u8(len(packet)) + bytes(packet)


def xcp_near(pid, *fields, segment=0, offset=0):
    """A command whose address (bytes 4..7) the target sets to segment's address + offset."""
    packet = bytes([pid, *fields]).ljust(4, b"\0") + bytes([segment, offset & 0xFF, 0, 0])
    return u8(XCP_CMD_NEAR) + u8(len(packet)) + packet


def xcp_stream(*packets, checksum=False, corrupt=False):
    """Packets framed with the LEN/CTR header (and the checksum byte), fed to the receiver byte by byte."""
    stream = b""
    for counter, packet in enumerate(packets):
        frame = struct.pack("<HH", len(packet), counter) + bytes(packet)
        if checksum:
            frame += u8((sum(frame) + (1 if corrupt else 0)) & 0xFF)
        stream += frame
    return u8(XCP_STREAM) + u8(len(stream)) + stream


def xcp_ops(*ops):
    return b"".join(u8(op) + bytes(args) for op, *args in ops)


CONNECT = xcp(0xFF, 0)
TAKE = u8(XCP_TAKE)
DAQ_SETUP = (
    xcp(0xD6)
    + xcp(0xD5, 0, 2, 0)
    + xcp(0xD4, 0, 0, 0, 2)
    + xcp(0xD4, 0, 1, 0, 1)
    + xcp(0xD3, 0, 0, 0, 0, 2)
    + xcp(0xD3, 0, 0, 0, 1, 1)
    + xcp(0xD3, 0, 1, 0, 0, 1)
    + xcp(0xE2, 0, 0, 0, 0, 0)
    + xcp_near(0xE1, 0xFF, 4, 0, segment=0, offset=0)
    + xcp_near(0xE1, 0xFF, 4, 0, segment=1, offset=0)
    + xcp(0xE2, 0, 0, 0, 1, 0)
    + xcp_near(0xE1, 0xFF, 8, 0, segment=2, offset=0)
    + xcp(0xE2, 0, 1, 0, 0, 0)
    + xcp_near(0xE1, 0xFF, 4, 0, segment=0, offset=36)
    + xcp(0xE0, 0x10, 0, 0, 0, 0, 1, 0)
    + xcp(0xE0, 0x00, 1, 0, 1, 0, 3, 0)
    + xcp(0xDE, 1, 0, 0)
    + xcp(0xDE, 2, 1, 0)
    + xcp(0xDD, 1)
    + TAKE
)
DAQ_RUN = (
    xcp_ops((XCP_EVENT, 0), (XCP_EVENT, 1), (XCP_EVENT, 1), (XCP_CLOCK, 50, 0), (XCP_EVENT, 1), (XCP_EVENT, 0))
    + TAKE
    + xcp_near(0xF6, 0, 0, 0, segment=1, offset=4)
    + xcp(0xF0, 4, 1, 2, 3, 4)
    + xcp_ops((XCP_EVENT, 0), (XCP_CALIBRATE, 1), (XCP_EVENT, 0))
    + TAKE
    + xcp(0xDD, 0)
    + TAKE
)

XCP_SEEDS = {
    # identification, uploads inside, across and beyond the segments, slave block mode
    "connect_upload": xcp_config()
    + CONNECT
    + xcp(0xFD)
    + xcp(0xFA, 0)
    + xcp(0xF5, 4)
    + xcp_near(0xF6, 0, 0, 0, segment=0, offset=0)
    + xcp(0xF5, 255)
    + xcp_near(0xF4, 40, 0, 0, segment=0, offset=0)
    + xcp_near(0xF4, 2, 0, 0, segment=2, offset=7)
    + xcp_near(0xF4, 4, 0, 0, segment=1, offset=-2)
    + TAKE,
    # downloads accepted, rejected, write protected, across the edge of the calibration segment
    "calibrate": xcp_config(cto=0)
    + CONNECT
    + xcp_near(0xF6, 0, 0, 0, segment=1, offset=0)
    + xcp(0xF0, 4, 1, 2, 3, 4)
    + xcp_ops((XCP_CALIBRATE, 1))
    + TAKE
    + xcp(0xF0, 4, 5, 6, 7, 8)
    + xcp_ops((XCP_CALIBRATE, 0))
    + TAKE
    + xcp_near(0xF6, 0, 0, 0, segment=1, offset=10)
    + xcp(0xF0, 4, 1, 2, 3, 4)
    + xcp_near(0xF6, 0, 0, 0, segment=1, offset=-1)
    + xcp(0xF0, 2, 1, 2)
    + TAKE,
    # dynamic DAQ lists on both events, sampled while a calibration write lands, then stopped
    "daq": xcp_config() + CONNECT + DAQ_SETUP + DAQ_RUN,
    # the same with CAN-sized packets (MAX_CTO 8, MAX_DTO 8) and a small queue
    "daq_can": xcp_config(cto=0, dto=0, queue=4) + CONNECT + DAQ_SETUP + DAQ_RUN,
    # both resources locked: refused, unlocked with the right key, a wrong key ends the session
    "seed_key": xcp_config(options=3)
    + CONNECT
    + xcp(0xF0, 1, 0)
    + xcp(0xF8, 0, 1)
    + xcp(0xF7, 1, 0)
    + xcp(0xF8, 0, 4)
    + xcp(0xF7, 1, 1)
    + xcp(0xFD)
    + CONNECT
    + xcp(0xDA)
    + TAKE,
    # framed packets with checksums, one corrupt, on the byte stream
    "stream": xcp_config(options=8)
    + xcp_stream([0xFF, 0], [0xFD], checksum=True)
    + xcp_stream([0xFD], checksum=True, corrupt=True)
    + xcp_stream([0xFA, 1], [0xF5, 8], checksum=True)
    + TAKE,
    # a master silent beyond the link timeout, then back
    "watchdog": xcp_config() + CONNECT + xcp_ops((XCP_CLOCK, 0xF4, 1), (XCP_CLOCK, 0xF4, 1)) + xcp(0xFD) + TAKE,
}


# operations (op % 8) of the fixed-point speed target (fuzz_speed_fixed.c); SAMPLE and the others as above
FIXED_PROBE = 3
I32_MIN, I32_MAX = -(2**31), 2**31 - 1


def fixed_config(surface=True, T_fs=nominal(), W_fs=nominal(), I_fs=nominal(), **speed):
    """Fixed-point configuration: its shape byte (bit 0: surface), a speed configuration, the full scales."""
    return u8(1 if surface else 0) + speed_config(surface=surface, **speed) + T_fs + W_fs + I_fs


def i32(v):
    return struct.pack("<i", v)


def fixed_sample(w_ref, w_m, mode=0, applied=0):
    """One sample of both formats: Q31 integers (Q15 takes their upper halves); mode 0 own T_ref, 1 applied, 2 u."""
    return u8(SAMPLE + 8 * mode) + i32(w_ref) + i32(w_m) + i32(applied)


def fixed_closed_loop(n, w_ref, T_load):
    return u8(CLOSED_LOOP) + u16(n - 1) + w_ref + T_load


# saturating samples at the extremes, reversing, with every applied torque; a constant reference while saturated
EXTREMES = (
    fixed_sample(I32_MAX, I32_MIN)
    + fixed_sample(I32_MAX, I32_MIN)
    + fixed_sample(I32_MAX, I32_MIN, mode=1, applied=I32_MIN)
    + fixed_sample(I32_MIN, I32_MAX, mode=1, applied=I32_MAX)
    + fixed_sample(I32_MIN, I32_MAX)
    + fixed_sample(I32_MIN, I32_MIN, mode=2)
    + fixed_sample(0, 1, mode=2)
    + fixed_sample(0, -1, mode=2)
    + u8(FIXED_PROBE)
)

SPEED_FIXED_SEEDS = {
    # the paper's drive scaled to twice its torque limit: a step under load, the dead-zone probe, a reversal
    "paper_lowpass_backcalc_load": fixed_config()
    + fixed_closed_loop(2048, nominal(), nominal())
    + u8(FIXED_PROBE)
    + fixed_closed_loop(1500, nominal(-0.5), nominal()),
    # zeta = 0.5: Fr(0) = -4 full scales per full scale, the feedforward transient at its bound; clamping
    "extremes_lowpass_clamping": fixed_config(zeta=nominal(0.5), anti_windup=2) + EXTREMES,
    "extremes_forward_full_backcalc": fixed_config(m=nominal(2.0), method=0, feedforward=3) + EXTREMES,
    "extremes_backward_notau_none": fixed_config(m=nominal(0.5), method=1, feedforward=2, anti_windup=0) + EXTREMES,
    "extremes_tustin_none_clamping": fixed_config(feedforward=0, anti_windup=2, W_fs=nominal(50.0)) + EXTREMES,
    # a speed full scale of 1e-9 rad/s: Ki Ts per unit below 2^-32, which Q31 refuses; Q15 runs with its dead zone
    "q31_deaf_integrator": fixed_config(W_fs=raw(1e-9)) + EXTREMES + fixed_closed_loop(500, nominal(), nominal()),
    # updates: a fresh design with the scalings kept, new scalings (refused), resets
    "set_config_and_reset": fixed_config()
    + fixed_closed_loop(300, nominal(), nominal())
    + u8(SET_MUTATED)
    + speed_config(zeta=nominal(0.7))
    + u8(1)
    + fixed_closed_loop(300, nominal(), nominal())
    + u8(SET_FRESH)
    + fixed_config(T_fs=nominal(2.0))
    + u8(RESET)
    + i32(1 << 20)
    + i32(-(1 << 24))
    + fixed_sample(1 << 20, 1 << 20, mode=2)
    + u8(RESET)
    + i32(I32_MIN)
    + i32(I32_MAX)
    + EXTREMES,
    # a salient motor: both formats refuse it
    "rejected_salient": fixed_config(surface=False),
}


def main():
    for target, seeds in (
        ("speed", SPEED_SEEDS),
        ("speed_fixed", SPEED_FIXED_SEEDS),
        ("current", CURRENT_SEEDS),
        ("commission", COMMISSION_SEEDS),
        ("encoder", ENCODER_SEEDS),
        ("field_weakening", FIELD_WEAKENING_SEEDS),
        ("inertia", INERTIA_SEEDS),
        ("filter", FILTER_SEEDS),
        ("xcp", XCP_SEEDS),
    ):
        folder = CORPUS / target
        folder.mkdir(parents=True, exist_ok=True)
        for old in folder.glob("*.bin"):
            old.unlink()
        for name, data in seeds.items():
            (folder / f"{name}.bin").write_bytes(data)
        print(f"{folder}: {len(seeds)} seeds, {sum(len(d) for d in seeds.values())} bytes")


if __name__ == "__main__":
    main()
