/*
 * The firmware's XCP link (link.h): the slave of csrc/src/xcp.c on the board's
 * byte link, its segments and events, the calibration commits into the
 * controllers, the run control and the link guard.
 */
#include "link.h"

#include <math.h>
#include <stddef.h>

#include "board.h"
#include "capture.h"
#include "commission_task.h"
#include "foc.h"
#include "identify_task.h"
#include "schedule.h"

#define LINK_SEGMENTS_MAX 18u  /* the link's six, the capture's three, the two routines' and the board's */
#define LINK_MAX_CTO 255u      /* longest command or response [bytes] */
#define LINK_MAX_DTO 255u      /* longest DAQ packet [bytes] */
#define LINK_DAQ_BYTES 1536u   /* DAQ lists, ODTs and entries [bytes] */
#define LINK_QUEUE_BYTES 4096u /* DTO queue [bytes] */
#define LINK_RX_CHUNK 64u      /* bytes taken from the link per poll [bytes] */
#define LINK_TX_PACKETS 16u    /* packets handed to the link per poll [-] */
#define LINK_SCHEDULE_TOL 1e-9 /* entries within this share of Ts_speed of a sample have started [-] */

/* The segments of the link, in this order before the board's. */
enum {
    SEG_FOC_NOW = 0,
    SEG_STATUS,
    SEG_SPEED_CONFIG,
    SEG_CURRENT_CONFIG,
    SEG_COMMAND,
    SEG_REFERENCE,
    SEG_CAPTURE_CONFIG,
    SEG_CAPTURE_STATUS,
    SEG_CAPTURE_BUFFER,
    SEG_COMMISSION,
    SEG_IDENTIFY = SEG_COMMISSION + COMMISSION_SEGMENTS,
    SEG_BOARD = SEG_IDENTIFY + IDENTIFY_SEGMENTS
};

link_status_t link_status_now;            /* the link's report (measurement) */
p2d_speed_config_t link_speed_config;     /* the speed controller's configuration (calibration) */
p2d_current_config_t link_current_config; /* the current controller's configuration (calibration) */
link_command_t link_command;              /* the run control (calibration) */
link_reference_t link_reference;          /* the run's speed reference (calibration) */
static link_reference_t shadow_reference; /* the master's pages wait here for their commit (largest segment) */
static p2d_xcp_segment_t segments[LINK_SEGMENTS_MAX];
static p2d_xcp_event_t events[2];
static uint32_t daq_memory[LINK_DAQ_BYTES / 4u]; /* word-aligned DAQ tables */
static uint8_t queue[LINK_QUEUE_BYTES];
static p2d_xcp_t xcp;         /* the slave */
static p2d_xcp_frame_t frame; /* the byte link's framing (LEN CTR, as XCP on SxI and on TCP) */
static uint8_t tx[P2D_XCP_FRAME_HEADER_BYTES + LINK_MAX_DTO]; /* the frame being sent */
static uint32_t tx_bytes, tx_sent;                            /* its length and the bytes sent [bytes] */
static p2d_xcp_guard_t guard;                                 /* the reaction to a silent master */
static uint32_t current_per_speed;                            /* control interrupts per speed sample [-] */
static uint32_t tick;                                         /* control interrupts since the last speed sample [-] */
static double Ts_speed_s;                                     /* speed period [s] */
static uint32_t run_samples;                                  /* speed samples of the run [-] */
static uint32_t start_request; /* samples of a run to start at the next speed sample, 0: none */
static bool stop_request;      /* stop the run at the next speed sample */
static uint32_t run_master;    /* the slave's CONNECT count of the master that started the run or routine, 0: none */
static uint32_t master_heard;  /* link clock at that master's last command [ticks] */

const link_status_t *link_status(void) { return &link_status_now; }

bool link_daq_backlog(void) { return xcp.queue_used > LINK_QUEUE_BYTES / 2u; }

static uint32_t link_clock(void *user)
{
    (void)user;
    return link_status_now.periods;
}

static void link_lock(void *user)
{
    (void)user;
    board_link_lock();
}

static void link_unlock(void *user)
{
    (void)user;
    board_link_unlock();
}

/* The reference schedule of a page as schedule.h reads it, not checked. */
static schedule_t reference_entries(const link_reference_t *r)
{
    schedule_t s = {r->t_s, r->w_radps, r->ramp_s, r->n};
    return s;
}

/* The reference schedule of a page as schedule.h reads it; false when n is too large or an entry invalid. */
static bool reference_schedule(const link_reference_t *r, schedule_t *s)
{
    *s = reference_entries(r);
    return r->n <= LINK_SCHEDULE_MAX && schedule_valid(s);
}

/* Where n bytes at an XCP address are read: inside one measurement or calibration segment but the capture buffer;
   NULL when none holds them. */
static const uint8_t *readable(uint32_t address, uint32_t n)
{
    for (uint16_t i = 0; i < xcp.config.segment_count; ++i) {
        const p2d_xcp_segment_t *g = &segments[i];
        if (i != SEG_CAPTURE_BUFFER && address >= g->address && n <= g->size_bytes &&
            address - g->address <= g->size_bytes - n) {
            return (const uint8_t *)g->memory + (address - g->address);
        }
    }
    return NULL;
}

/* A capture page: valid, and its signals readable (capture.h); arms or disarms the capture. */
static bool capture_commit(const capture_config_t *c)
{
    const uint8_t *source[CAPTURE_SIGNALS_MAX];
    if (!capture_valid(c)) return false;
    for (uint32_t i = 0; c->command == 1u && i < c->n; ++i) {
        source[i] = readable(c->address[i], c->size[i]);
        if (source[i] == NULL) return false;
    }
    capture_command(c, source);
    return true;
}

/* A routine starts (commissioning, identification): the master that started it feeds its watchdog (master_silent). */
static void routine_master(void)
{
    run_master = xcp.connected ? xcp.connects : 0u;
    master_heard = xcp.last_command_ticks;
}

/* The commit callback: validate and apply the page of a calibration segment (0: applied). */
static int32_t link_commit(void *user, uint16_t index, const void *page)
{
    bool running = link_status_now.state == LINK_RUNNING;
    int32_t code = 0;
    (void)user;
    switch (index) {
    case SEG_SPEED_CONFIG: code = (int32_t)foc_set_speed_config((const p2d_speed_config_t *)page); break;
    case SEG_CURRENT_CONFIG: code = (int32_t)foc_set_current_config((const p2d_current_config_t *)page); break;
    case SEG_COMMAND: {
        const link_command_t *c = (const link_command_t *)page;
        schedule_t s;
        if (c->command > 2u || (c->command == 1u && c->samples == 0u)) {
            code = LINK_REJECT_COMMAND;
        } else if (c->command == 1u && !reference_schedule(&link_reference, &s)) {
            code = LINK_REJECT_SCHEDULE;
        } else if (c->command == 1u && (!board_run_valid() || commission_running() || identify_running())) {
            code = LINK_REJECT_BOARD;
        } else {
            start_request = c->command == 1u ? c->samples : 0u;
            stop_request = c->command == 2u;
        }
        break;
    }
    case SEG_CAPTURE_CONFIG:
        if (!capture_commit((const capture_config_t *)page)) code = LINK_REJECT_CAPTURE;
        break;
    case SEG_REFERENCE:
        /* a run plays its schedule to the end: the master changes it between runs (checked whole at the start) */
        if (running || ((const link_reference_t *)page)->n > LINK_SCHEDULE_MAX) code = LINK_REJECT_SCHEDULE;
        break;
    case SEG_COMMISSION:
    case SEG_COMMISSION + 1:
        code = commission_commit((uint16_t)(index - SEG_COMMISSION), page, running || identify_running());
        if (code == 0 && index == SEG_COMMISSION + 1 && ((const commission_command_t *)page)->command == 1u) {
            routine_master();
        }
        break;
    case SEG_IDENTIFY:
    case SEG_IDENTIFY + 1:
        code = identify_commit((uint16_t)(index - SEG_IDENTIFY), page, running || commission_running());
        if (code == 0 && index == SEG_IDENTIFY + 1 && ((const identify_command_t *)page)->command == 1u) {
            routine_master();
        }
        break;
    default: code = board_link_commit((uint16_t)(index - SEG_BOARD), page, running) ? 0 : LINK_REJECT_BOARD; break;
    }
    if (code == 0) {
        link_status_now.commit_run = link_status_now.runs;
        link_status_now.commit_sample = link_status_now.sample;
        link_status_now.commits_applied++;
    } else {
        link_status_now.commit_status = code;
        link_status_now.commits_rejected++;
    }
    return code;
}

/* Period of Ts_ns nanoseconds as XCP's cycle (1..255) and unit (10^unit ns); cycle 0 (sporadic) when too long. */
static void xcp_cycle(uint64_t Ts_ns, uint8_t *cycle, uint8_t *unit)
{
    uint8_t u = 0u;
    while (u < 9u && (Ts_ns > 255u || Ts_ns % 10u == 0u) && Ts_ns >= 10u) {
        Ts_ns /= 10u;
        u++;
    }
    *cycle = Ts_ns <= 255u ? (uint8_t)Ts_ns : 0u;
    *unit = u;
}

link_init_status_t link_init(const link_config_t *cfg)
{
    link_init_status_t st = {P2D_XCP_OK, true};
    p2d_xcp_config_t c = {0};
    p2d_xcp_guard_config_t g;
    uint64_t Ts_ns = (uint64_t)(cfg->Ts_current_s * 1e9 + 0.5);
    uint16_t n = SEG_COMMISSION;
    uint8_t unit;

    if (cfg->n > LINK_SCHEDULE_MAX) {
        st.schedule = false;
        return st;
    }
    link_reference.n = cfg->n;
    for (uint32_t i = 0; i < cfg->n; ++i) {
        link_reference.t_s[i] = cfg->t_s[i];
        link_reference.w_radps[i] = cfg->w_radps[i];
        link_reference.ramp_s[i] = cfg->ramp_s[i];
    }
    {
        schedule_t s;
        if (!reference_schedule(&link_reference, &s)) {
            st.schedule = false;
            return st;
        }
    }
    link_speed_config = *foc_speed_config();
    link_current_config = *foc_current_config();
    current_per_speed = cfg->current_per_speed;
    Ts_speed_s = cfg->Ts_current_s * (double)cfg->current_per_speed;
    start_request = cfg->autostart_samples;

    segments[SEG_FOC_NOW] =
        (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&foc_now, &foc_now, sizeof foc_now, P2D_XCP_MEASUREMENT};
    segments[SEG_STATUS] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&link_status_now, &link_status_now,
                                               sizeof link_status_now, P2D_XCP_MEASUREMENT};
    segments[SEG_SPEED_CONFIG] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&link_speed_config, &link_speed_config,
                                                     sizeof link_speed_config, P2D_XCP_CALIBRATION};
    segments[SEG_CURRENT_CONFIG] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&link_current_config, &link_current_config,
                                                       sizeof link_current_config, P2D_XCP_CALIBRATION};
    segments[SEG_COMMAND] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&link_command, &link_command, sizeof link_command,
                                                P2D_XCP_CALIBRATION};
    segments[SEG_REFERENCE] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&link_reference, &link_reference,
                                                  sizeof link_reference, P2D_XCP_CALIBRATION};
    segments[SEG_CAPTURE_CONFIG] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&capture_config, &capture_config,
                                                       sizeof capture_config, P2D_XCP_CALIBRATION};
    segments[SEG_CAPTURE_STATUS] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)&capture_status_now, &capture_status_now,
                                                       sizeof capture_status_now, P2D_XCP_MEASUREMENT};
    segments[SEG_CAPTURE_BUFFER] = (p2d_xcp_segment_t){(uint32_t)(uintptr_t)capture_buffer, capture_buffer,
                                                       sizeof capture_buffer, P2D_XCP_MEASUREMENT};
    commission_init((float)cfg->Ts_current_s);
    n = (uint16_t)(n + commission_link_segments(&segments[SEG_COMMISSION], COMMISSION_SEGMENTS));
    identify_init((float)cfg->Ts_current_s);
    n = (uint16_t)(n + identify_link_segments(&segments[SEG_IDENTIFY], IDENTIFY_SEGMENTS));
    n = (uint16_t)(n + board_link_segments(&segments[SEG_BOARD], (uint16_t)(LINK_SEGMENTS_MAX - SEG_BOARD)));

    xcp_cycle(Ts_ns, &events[0].cycle, &unit);
    events[0] = (p2d_xcp_event_t){"current", events[0].cycle, unit, 2u};
    xcp_cycle(Ts_ns * cfg->current_per_speed, &events[1].cycle, &unit);
    events[1] = (p2d_xcp_event_t){"speed", events[1].cycle, unit, 1u};

    c.segments = segments;
    c.segment_count = n;
    c.shadow = &shadow_reference;
    c.shadow_bytes = sizeof shadow_reference;
    c.events = events;
    c.event_count = 2u;
    c.daq_memory = daq_memory;
    c.daq_memory_bytes = sizeof daq_memory;
    c.queue = queue;
    c.queue_bytes = sizeof queue;
    if (cfg->max_packet_bytes < 8u || cfg->max_packet_bytes > LINK_MAX_CTO) {
        st.xcp = P2D_XCP_ERR_MAX_CTO;
        return st;
    }
    c.max_cto = (uint8_t)cfg->max_packet_bytes;
    c.max_dto = (uint16_t)cfg->max_packet_bytes;
    /* timestamps in control periods: one tick = Ts_current, as a whole number of 10^unit ns */
    unit = 0u;
    while (unit < 9u && Ts_ns % 10u == 0u && Ts_ns >= 10u) {
        Ts_ns /= 10u;
        unit++;
    }
    c.timestamp_unit = unit;
    c.timestamp_ticks = Ts_ns <= 65535u ? (uint16_t)Ts_ns : 65535u;
    c.link_timeout_ticks = (uint32_t)((double)cfg->timeout_s / cfg->Ts_current_s + 0.5);
    c.id = "pmsm2dof firmware (examples/firmware)";
    c.a2l_name = "firmware";
    c.clock = link_clock;
    c.commit = link_commit;
    c.lock = link_lock;
    c.unlock = link_unlock;
    st.xcp = p2d_xcp_init(&xcp, &c);
    if (st.xcp != P2D_XCP_OK) return st;
    g.Ts_s = (float)Ts_speed_s;
    g.ramp_radps_per_s = cfg->ramp_radps_per_s;
    g.hold_s = cfg->hold_s;
    st.xcp = p2d_xcp_guard_init(&guard, &g);
    if (st.xcp != P2D_XCP_OK) return st;
    p2d_xcp_frame_init(&frame, false);
    return st;
}

/* Switch the power stage and report it. */
static void power(bool on)
{
    if ((link_status_now.power_on != 0u) != on) board_pwm_enable(on);
    link_status_now.power_on = on ? 1u : 0u;
}

/* A run starts at this speed sample: the drive from its initial state, the schedules from t = 0. */
static void start_run(uint32_t samples)
{
    float w_m_radps, T_Nm;
    board_read_start_state(&w_m_radps, &T_Nm);
    foc_start(w_m_radps, T_Nm);
    board_run_begin();
    p2d_xcp_guard_reset(&guard);
    run_master = xcp.connected ? xcp.connects : 0u;
    master_heard = xcp.last_command_ticks;
    run_samples = samples;
    link_status_now.state = LINK_RUNNING;
    link_status_now.runs++;
    link_status_now.sample = 0u;
    link_status_now.trip_sample = 0u;
    link_status_now.stop_sample = 0u;
    power(true);
}

/*
 * The master of the run (or routine) is silent: the slave's watchdog, or the master that started it gone (it
 * disconnected, or another CONNECT came: a new master, or the same after a cut) for longer than the link timeout
 * since its last command. Only that master feeds the guard; a run started at power-up (no master) is fed by any.
 */
static bool master_silent(void)
{
    bool silent = p2d_xcp_link_check(&xcp);
    if (run_master == 0u || (xcp.connected && xcp.connects == run_master)) return silent;
    return xcp.config.link_timeout_ticks > 0u && link_status_now.periods - master_heard > xcp.config.link_timeout_ticks;
}

/* The speed sample of a run: the schedule's reference through the link guard. */
static void run_sample(void)
{
    link_status_t *s = &link_status_now;
    /* checked whole when the run started, and unchanged during it (link_commit) */
    schedule_t r = reference_entries(&link_reference);
    bool on, silent = master_silent();
    double t_s = (double)s->sample * Ts_speed_s;
    float w_ref_radps;
    s->t_s = t_s;
    s->w_cmd_radps = schedule_value(&r, t_s, LINK_SCHEDULE_TOL * Ts_speed_s);
    w_ref_radps = p2d_xcp_guard_step(&guard, silent, (float)s->w_cmd_radps, &on);
    s->guard_state = (uint32_t)guard.state;
    /* armed: the schedule's value in double, as the engine logs its reference */
    s->w_ref_radps = guard.state == P2D_XCP_GUARD_ARMED ? s->w_cmd_radps : (double)w_ref_radps;
    if (guard.state != P2D_XCP_GUARD_ARMED && s->trip_sample == 0u) s->trip_sample = s->sample;
    if (!on) {
        s->stop_sample = s->sample;
        s->state = LINK_TRIPPED;
        power(false);
        return;
    }
    foc_set_speed_reference(w_ref_radps);
}

void link_isr(void)
{
    link_status_t *s = &link_status_now;
    bool speed = tick == 0u; /* foc_isr's own count agrees: both start a run at a speed sample */
    bool run_start = false;
    s->periods++;
    if (speed) {
        /* the master's calibration takes effect here, all at once, before the control */
        (void)p2d_xcp_calibrate(&xcp);
        if (stop_request && s->state == LINK_RUNNING) {
            s->state = LINK_STOPPED;
            power(false);
        }
        stop_request = false;
        if (start_request > 0u) {
            start_run(start_request);
            start_request = 0u;
            run_start = true;
        }
        if (s->state == LINK_RUNNING) {
            if (s->sample == run_samples) {
                s->state = LINK_DONE;
                power(false);
            } else {
                run_sample();
            }
        }
    }
    if (s->state == LINK_RUNNING) {
        foc_isr();
    } else {
        /* between runs: the routine the master started (one at a time), the watchdog of its master over it */
        bool silent = (commission_running() || identify_running()) && master_silent();
        bool on = commission_isr(silent && commission_running());
        power(identify_isr(silent && identify_running()) || on);
    }
    tick = tick + 1u == current_per_speed ? 0u : tick + 1u;
    s->dtos_lost = xcp.dtos_lost;
    p2d_xcp_event(&xcp, 0u);
    capture_sample(speed, run_start, s->periods);
    if (speed) {
        p2d_xcp_event(&xcp, 1u);
        if (s->state == LINK_RUNNING) s->sample++;
    }
}

void link_poll(void)
{
    uint8_t rx[LINK_RX_CHUNK];
    uint32_t n = board_link_receive(rx, LINK_RX_CHUNK);
    for (uint32_t i = 0; i < n; ++i) {
        uint32_t len = p2d_xcp_frame_rx(&frame, rx[i]);
        if (len > 0u) {
            p2d_xcp_command(&xcp, frame.packet, len);
            /* the run's master spoke (its DISCONNECT too); another's CONNECT changes the count */
            if (xcp.connects == run_master) master_heard = xcp.last_command_ticks;
        }
    }
    for (uint32_t k = 0; k < LINK_TX_PACKETS; ++k) {
        if (tx_sent == tx_bytes) {
            uint32_t len = p2d_xcp_take(&xcp, tx + P2D_XCP_FRAME_HEADER_BYTES, LINK_MAX_DTO);
            if (len == 0u) return;
            tx_bytes = p2d_xcp_frame_tx(&frame, tx, len);
            tx_sent = 0u;
        }
        tx_sent += board_link_send(tx + tx_sent, tx_bytes - tx_sent);
        if (tx_sent < tx_bytes) return; /* the link is busy: the rest at the next poll */
    }
}
