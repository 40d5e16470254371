#include "pmsm2dof/status.h"

typedef struct {
    const char *param; /* configuration field */
    const char *range; /* valid range */
} p2d_status_text_t;

static const p2d_status_text_t P2D_STATUS_TEXT[P2D_STATUS_COUNT] = {
    [P2D_OK] = {"", ""},
    [P2D_ERR_NULL] = {"pointer", "non-NULL"},
    [P2D_ERR_J] = {"J_kgm2",
                   "finite and > 0, with the gains Kp = J*alpha and Ki = J*(alpha/(2*zeta))^2 normal float32 numbers "
                   "(about 1.2e-38 to 3.4e38)"},
    [P2D_ERR_ALPHA] = {"alpha_radps", "finite and > 0"},
    [P2D_ERR_ZETA] = {"zeta", "finite and > 0"},
    [P2D_ERR_M] = {"m", "finite and > 0"},
    [P2D_ERR_M_LOWPASS] = {"m", "exactly 1 with feedforward lowpass (eq 13); use no_tau or full for m != 1"},
    [P2D_ERR_TAU_I] = {"tau_i_s", "finite and >= 0 (speed controller); finite and >= Ts_s (current controller), with "
                                  "the gains L/tau_i_s and Rs/tau_i_s finite in float32; finite and >= 10 Ts_s "
                                  "(commissioning)"},
    [P2D_ERR_KA] = {"Ka", "finite and >= 0, and Ki*Ka*Ts_s < 2 with back_calculation (stable discrete anti-windup "
                          "loop; with torque filters, the loop through them stable too, speed.h)"},
    [P2D_ERR_TS] = {"Ts_s", "finite and > 0"},
    [P2D_ERR_TS_UNSTABLE] =
        {"Ts_s", "small enough that every discrete pole stays inside the unit circle (forward-Euler feedforward: "
                 "m*alpha*Ts_s < 2; current back calculation: Rs*Ts_s/min(Ld, Lq) < 2; and m*alpha*Ts_s neither so "
                 "small, nor with tustin so large, that float32 rounds the feedforward pole onto the unit circle)"},
    [P2D_ERR_I_MAX] = {"i_max_A", "finite and > 0"},
    [P2D_ERR_POLE_PAIRS] = {"pole_pairs", "an integer >= 1"},
    [P2D_ERR_PSI_F] = {"psi_f_Wb", "finite and > 0 (speed controller), >= 0 (current controller)"},
    [P2D_ERR_LD] = {"Ld_H", "finite and > 0"},
    [P2D_ERR_LQ] = {"Lq_H", "finite and > 0"},
    [P2D_ERR_RS] = {"Rs_ohm", "finite and > 0"},
    [P2D_ERR_METHOD] = {"method", "forward_euler (0), backward_euler (1) or tustin (2)"},
    [P2D_ERR_FEEDFORWARD] = {"feedforward", "none (0), lowpass (1), no_tau (2) or full (3)"},
    [P2D_ERR_ANTI_WINDUP] = {"anti_windup", "none (0), back_calculation (1) or clamping (2)"},
    [P2D_ERR_I_TEST] = {"i_test_A", "finite and > 0"},
    [P2D_ERR_I_SPIN] = {"i_spin_A", "finite and > 0"},
    [P2D_ERR_I_TRIP] = {"i_trip_A",
                        ">= 1.5 max(i_test_A, i_spin_A), with i_trip_A^2 a normal float32 (1.1e-19 A to 1.8e19 A)"},
    [P2D_ERR_T_ALIGN] = {"t_align_s", "finite, >= 20 tau_i_s and <= 2^24 Ts_s"},
    [P2D_ERR_T_LEVEL] = {"t_level_s", "finite, >= 20 tau_i_s and <= 2^24 Ts_s"},
    [P2D_ERR_T_INDUCTANCE] = {"t_inductance_s", "finite, >= 64 Ts_s and <= 2^24 Ts_s"},
    [P2D_ERR_T_RAMP] = {"t_ramp_s", "finite, >= 100 Ts_s and <= 2^24 Ts_s"},
    [P2D_ERR_T_SPIN] = {"t_spin_s", "finite, >= 20 tau_i_s and <= 2^24 Ts_s"},
    [P2D_ERR_W_E_SPIN] = {"w_e_spin_radps", "finite, > 0 and <= 0.1 / Ts_s (at least 63 samples per electrical turn)"},
    [P2D_ERR_VOLTAGE_DELAY] = {"voltage_delay_samples", "0 or 1"},
    [P2D_ERR_ENC_COUNTS_PER_REV] = {"counts_per_rev", "an integer >= 1, with 2*pi/(counts_per_rev*Ts_s) finite "
                                                      "and > 0 in float32"},
    [P2D_ERR_ENC_COUNTER_BITS] = {"counter_bits", "an integer from 2 to 32"},
    [P2D_ERR_ENC_ESTIMATOR] = {"estimator", "difference (0) or pll (1)"},
    [P2D_ERR_ENC_BANDWIDTH] = {"bandwidth_radps", "finite and 1e-3 <= bandwidth_radps*Ts_s <= 2 (pll: real discrete "
                                                  "poles, increments above the float32 resolution of the state)"},
    [P2D_ERR_ENC_LOWPASS] = {"lowpass_radps", "0 (no filter), or finite and 1e-3 <= lowpass_radps*Ts_s <= 2"},
    [P2D_ERR_FW_KP] = {"Kp_A_per_V", "finite and >= 0"},
    [P2D_ERR_FW_KI] = {"Ki_A_per_Vs", "finite and > 0, with Ki_A_per_Vs*Ts_s finite and > 0 in float32"},
    [P2D_ERR_FW_KA] = {"Ka_V_per_A", "finite and >= 0, and Ki_A_per_Vs*Ka_V_per_A*Ts_s < 2 with back_calculation "
                                     "(stable discrete anti-windup loop)"},
    [P2D_ERR_FW_VOLTAGE_RATIO] = {"voltage_ratio", "finite, > 0 and <= 1 (share of u_dc/sqrt(3))"},
    [P2D_ERR_FW_ID_MIN] = {"id_min_A", "finite and < 0"},
    [P2D_ERR_J0] = {"J0_kgm2", "finite and > 0, with J0_kgm2^2 a normal float32 (about 1.1e-19 to 1.8e19 kg m^2)"},
    [P2D_ERR_J_MIN] = {"J_min_kgm2", "finite, > 0 and <= J0_kgm2"},
    [P2D_ERR_J_MAX] = {"J_max_kgm2", "finite and >= J0_kgm2"},
    [P2D_ERR_B_MAX] = {"B_max_Nms",
                       "finite and > 0, with B_max_Nms^2 a normal float32 (about 1.1e-19 to 1.8e19 Nm s/rad)"},
    [P2D_ERR_T_LOAD_MAX] = {"T_load_max_Nm",
                            "finite and > 0, with T_load_max_Nm^2 a normal float32 (about 1.1e-19 to 1.8e19 Nm)"},
    [P2D_ERR_SIGMA_T] = {"sigma_T_Nm",
                         "finite and > 0, with sigma_T_Nm^2 a normal float32 (about 1.1e-19 to 1.8e19 Nm)"},
    [P2D_ERR_J_MEMORY] = {"J_memory_s", "finite, >= 2*Ts_s and <= 1e6*Ts_s"},
    [P2D_ERR_LOAD_MEMORY] = {"load_memory_s", "finite, >= 2*Ts_s and <= 1e6*Ts_s"},
    [P2D_ERR_W_F] = {"w_f_radps", "finite and > 0, with w_f_radps*Ts_s >= 1e-6"},
    [P2D_ERR_J_REL_SD_MAX] = {"J_rel_sd_max", "finite, > 0 and < 1"},
    [P2D_ERR_NOTCH_FREQ] = {"notch_freq_Hz", "0 (no notch), or finite and > 0, below the Nyquist frequency 1/(2*Ts_s): "
                                             "notch_freq_Hz*Ts_s between about 1e-19 and 0.495 (float32)"},
    [P2D_ERR_NOTCH_WIDTH] = {"notch_width_Hz", "finite, > 0 and below 1/(2*Ts_s) (the -3 dB bandwidth of the notch), "
                                               "with notch_width_Hz*Ts_s above about 1e-37, and B = (1 + g^2) "
                                               "tan(pi*notch_width_Hz*Ts_s)/sqrt(1 - 2*notch_depth^2) at most "
                                               "4000 - g^2, g = tan(pi*notch_freq_Hz*Ts_s) (float32)"},
    [P2D_ERR_NOTCH_DEPTH] = {"notch_depth", "finite, >= 0 and < 1/sqrt(2) = 0.7071 (the gain at notch_freq_Hz; the "
                                            "width is measured at -3 dB)"},
    [P2D_ERR_LOWPASS_FREQ] = {"lowpass_freq_Hz", "0 (no low-pass), or finite and > 0, below the Nyquist frequency "
                                                 "1/(2*Ts_s): lowpass_freq_Hz*Ts_s between about 1e-19 and 0.495 "
                                                 "(float32)"},
    [P2D_ERR_LOWPASS_ZETA] = {"lowpass_zeta", "finite and > 0 (1/sqrt(2): -3 dB at lowpass_freq_Hz, no peak), with "
                                              "g (g + 2*lowpass_zeta) at most 4000 and lowpass_zeta*g above about "
                                              "1e-37, g = tan(pi*lowpass_freq_Hz*Ts_s) (float32)"},
    [P2D_ERR_SPEED_FULL_SCALE] =
        {"speed_full_scale_radps",
         "finite and > 0, with every speed-to-torque gain (Kp + Ki*Ts_s, Ki*Ts_s, Fr(0) and the "
         "feedforward's) times speed_full_scale_radps/torque_full_scale_Nm below 2^13, in Q31 "
         "Ki*Ts_s*speed_full_scale_radps/torque_full_scale_Nm >= 2^-32 (one LSB of error moves "
         "the integrator), and unchanged by set_config (fixed-point speed controllers)"},
    [P2D_ERR_TORQUE_FULL_SCALE] = {"torque_full_scale_Nm",
                                   "finite, >= the torque limit 1.5*pole_pairs*psi_f_Wb*i_max_A, which must be at "
                                   "least one LSB (torque_full_scale_Nm/2^15 in Q15, /2^31 in Q31), and unchanged by "
                                   "set_config (fixed-point speed controllers)"},
    [P2D_ERR_CURRENT_FULL_SCALE] = {"current_full_scale_A",
                                    "finite, >= i_max_A, which must be at least one LSB (current_full_scale_A/2^15 in "
                                    "Q15, /2^31 in Q31), with torque_full_scale_Nm/(1.5*pole_pairs*psi_f_Wb*"
                                    "current_full_scale_A) below 2^13, and unchanged by set_config (fixed-point speed "
                                    "controllers)"},
    [P2D_ERR_SALIENT] = {"Lq_H", "equal to Ld_H in the fixed-point speed controllers (surface PMSM: id = 0, |iq| <= "
                                 "i_max_A; no integer MTPA)"},
};

const char *p2d_status_param(p2d_status_t status)
{
    if ((unsigned)status >= (unsigned)P2D_STATUS_COUNT) {
        return "unknown";
    }
    return P2D_STATUS_TEXT[status].param;
}

const char *p2d_status_range(p2d_status_t status)
{
    if ((unsigned)status >= (unsigned)P2D_STATUS_COUNT) {
        return "unknown status code";
    }
    return P2D_STATUS_TEXT[status].range;
}
