/*
 * A host program that runs the XCP slave (xcp.h) over TCP on 127.0.0.1, the
 * way the firmware runs it: a periodic thread plays the interrupts (the
 * "current" event every period, the "speed" sample and event every
 * speed_divider periods, with the calibration commit, the link watchdog and
 * its guard), the main thread plays the transport (frames in, packets out).
 * The drive is a stand-in: the speed follows the applied reference through a
 * first-order lag tau_s. tests/test_xcp_slave.py drives it with pyxcp.
 *
 * Memory the master may reach:
 *   0x00010000  measurement  drive_meas_t (below)
 *   0x00020000  calibration  drive_cal_t; the commit rejects a tau_s outside (0, 10] s,
 *                            a limit outside (0, 1e4] rad/s, or |w_cmd| above the limit
 *   0x00030000  measurement  the slave's counter of lost DAQ samples (uint32)
 *
 * usage: xcp_tcp_slave [--port N] [--period-us N] [--speed-divider N] [--link-timeout-ms N]
 *                      [--ramp-radps-per-s X] [--hold-s X] [--protect] [--max-cto N] [--max-dto N]
 *                      [--queue-bytes N] [--lifetime-s N]
 * It prints "port N" once listening, serves one master at a time, and exits after lifetime_s.
 */
#define _POSIX_C_SOURCE 200809L

#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "pmsm2dof/xcp.h"

#define MEAS_ADDRESS 0x00010000u
#define CAL_ADDRESS 0x00020000u
#define LOST_ADDRESS 0x00030000u

typedef struct {
    uint32_t sample;           /* speed samples since start */
    uint32_t current_count;    /* current events since start */
    float w_ref_radps;         /* reference applied (after the guard) [rad/s] */
    float w_m_radps;           /* speed of the stand-in drive [rad/s] */
    uint32_t command_sample;   /* sample of the last command received */
    uint32_t trip_sample;      /* sample at which the guard left ARMED (0: never) */
    uint32_t stop_sample;      /* sample at which the guard disabled the power stage (0: never) */
    uint32_t silent_samples;   /* trip_sample - command_sample at the trip: the silence that tripped it */
    uint8_t power_on;          /* 1 while the power stage may be on */
    uint8_t guard_state;       /* p2d_xcp_guard_state_t */
    uint16_t commits_rejected; /* calibration pages rejected */
} drive_meas_t;

typedef struct {
    float w_cmd_radps; /* the master's speed reference [rad/s] */
    float tau_s;       /* time constant of the stand-in drive [s] */
    float limit_radps; /* largest |w_cmd_radps| accepted [rad/s] */
} drive_cal_t;

typedef struct {
    int port;
    long period_us;
    int speed_divider;
    long link_timeout_ms;
    float ramp_radps_per_s;
    float hold_s;
    int protect;
    int max_cto;
    int max_dto;
    long queue_bytes;
    long lifetime_s;
} options_t;

typedef struct {
    options_t opt;
    pthread_mutex_t mutex;
    drive_meas_t meas;
    drive_cal_t cal;
    drive_cal_t shadow;
    p2d_xcp_segment_t segments[3];
    p2d_xcp_event_t events[2];
    uint8_t daq_memory[4096];
    uint8_t *queue;
    p2d_xcp_t xcp;
    p2d_xcp_guard_t guard;
    struct timespec start;
    volatile int stop;
} app_t;

static uint32_t clock_us(void *user)
{
    const app_t *a = (const app_t *)user;
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint32_t)((t.tv_sec - a->start.tv_sec) * 1000000L + (t.tv_nsec - a->start.tv_nsec) / 1000L);
}

static void app_lock(void *user) { pthread_mutex_lock(&((app_t *)user)->mutex); }

static void app_unlock(void *user) { pthread_mutex_unlock(&((app_t *)user)->mutex); }

/* the drive's validation of a new calibration page (as p2d_speed_set_config would validate its configuration) */
static int32_t commit(void *user, uint16_t segment, const void *page)
{
    drive_cal_t c;
    (void)user;
    (void)segment;
    memcpy(&c, page, sizeof c);
    if (!(c.tau_s > 0.0f && c.tau_s <= 10.0f)) return 1;
    if (!(c.limit_radps > 0.0f && c.limit_radps <= 1e4f)) return 2;
    if (!(fabsf(c.w_cmd_radps) <= c.limit_radps)) return 3;
    return 0;
}

/* the key: each seed byte xor 0xA5, then the seed reversed */
static uint8_t key(void *user, uint8_t resource, const uint8_t *seed, uint8_t seed_bytes, uint8_t *out)
{
    (void)user;
    (void)resource;
    for (uint8_t i = 0; i < seed_bytes; ++i) {
        out[i] = (uint8_t)(seed[i] ^ 0xA5u);
        out[seed_bytes + i] = seed[seed_bytes - 1u - i];
    }
    return (uint8_t)(2u * seed_bytes);
}

static void speed_sample(app_t *a)
{
    float Ts = 1e-6f * (float)(a->opt.period_us * a->opt.speed_divider);
    bool on, silent;
    float w_ref;
    (void)p2d_xcp_calibrate(&a->xcp); /* the master's calibration takes effect here, all at once */
    silent = p2d_xcp_link_check(&a->xcp);
    pthread_mutex_lock(&a->mutex);
    w_ref = p2d_xcp_guard_step(&a->guard, silent, a->cal.w_cmd_radps, &on);
    a->meas.sample++;
    if (a->guard.state != P2D_XCP_GUARD_ARMED && a->meas.trip_sample == 0u) {
        a->meas.trip_sample = a->meas.sample;
        a->meas.silent_samples = a->meas.sample - a->meas.command_sample;
    }
    if (!on && a->meas.stop_sample == 0u) a->meas.stop_sample = a->meas.sample;
    a->meas.w_ref_radps = w_ref;
    /* w[k] = w[k-1] + (w_ref - w[k-1]) (1 - exp(-Ts / tau)) while powered; coasting otherwise (no friction) */
    if (on) a->meas.w_m_radps += (w_ref - a->meas.w_m_radps) * (1.0f - expf(-Ts / a->cal.tau_s));
    a->meas.power_on = on ? 1u : 0u;
    a->meas.guard_state = (uint8_t)a->guard.state;
    a->meas.commits_rejected = (uint16_t)a->xcp.commits_rejected;
    pthread_mutex_unlock(&a->mutex);
    p2d_xcp_event(&a->xcp, 1);
}

static void *interrupts(void *arg)
{
    app_t *a = (app_t *)arg;
    struct timespec next;
    long tick = 0;
    clock_gettime(CLOCK_MONOTONIC, &next);
    while (!a->stop) {
        next.tv_nsec += a->opt.period_us * 1000L;
        while (next.tv_nsec >= 1000000000L) {
            next.tv_nsec -= 1000000000L;
            next.tv_sec++;
        }
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL);
        pthread_mutex_lock(&a->mutex);
        a->meas.current_count++;
        pthread_mutex_unlock(&a->mutex);
        p2d_xcp_event(&a->xcp, 0);
        if (++tick % a->opt.speed_divider == 0) speed_sample(a);
    }
    return NULL;
}

static int send_all(int fd, const uint8_t *bytes, size_t n)
{
    while (n > 0) {
        ssize_t sent = send(fd, bytes, n, 0);
        if (sent < 0 && errno == EINTR) continue;
        if (sent <= 0) return -1;
        bytes += sent;
        n -= (size_t)sent;
    }
    return 0;
}

/* Serve one master until it closes the connection or the lifetime ends. */
static void serve(app_t *a, int fd, long deadline_s)
{
    p2d_xcp_frame_t link;
    uint8_t rx[4096], frame[P2D_XCP_FRAME_HEADER_BYTES + 65536];
    p2d_xcp_frame_init(&link, false);
    while (time(NULL) < deadline_s) {
        struct pollfd p = {fd, POLLIN, 0};
        int ready = poll(&p, 1, 1);
        size_t n;
        if (ready > 0) {
            ssize_t got = recv(fd, rx, sizeof rx, 0);
            if (got <= 0) return;
            for (ssize_t i = 0; i < got; ++i) {
                size_t len = p2d_xcp_frame_rx(&link, rx[i]);
                if (len == 0) continue;
                p2d_xcp_command(&a->xcp, link.packet, len);
                pthread_mutex_lock(&a->mutex);
                a->meas.command_sample = a->meas.sample;
                pthread_mutex_unlock(&a->mutex);
            }
        }
        while ((n = p2d_xcp_take(&a->xcp, frame + P2D_XCP_FRAME_HEADER_BYTES, sizeof frame - 5)) > 0) {
            if (send_all(fd, frame, p2d_xcp_frame_tx(&link, frame, n)) != 0) return;
        }
    }
}

static long option(int argc, char **argv, const char *name, long fallback)
{
    for (int i = 1; i + 1 < argc; ++i) {
        if (strcmp(argv[i], name) == 0) return strtol(argv[i + 1], NULL, 10);
    }
    return fallback;
}

static float option_float(int argc, char **argv, const char *name, float fallback)
{
    for (int i = 1; i + 1 < argc; ++i) {
        if (strcmp(argv[i], name) == 0) return strtof(argv[i + 1], NULL);
    }
    return fallback;
}

static int configure(app_t *a)
{
    p2d_xcp_config_t c;
    p2d_xcp_guard_config_t g;
    p2d_xcp_status_t status;
    memset(&c, 0, sizeof c);
    a->segments[0] = (p2d_xcp_segment_t){MEAS_ADDRESS, &a->meas, sizeof a->meas, P2D_XCP_MEASUREMENT};
    a->segments[1] = (p2d_xcp_segment_t){CAL_ADDRESS, &a->cal, sizeof a->cal, P2D_XCP_CALIBRATION};
    a->segments[2] = (p2d_xcp_segment_t){LOST_ADDRESS, &a->xcp.dtos_lost, sizeof a->xcp.dtos_lost, P2D_XCP_MEASUREMENT};
    a->events[0] = (p2d_xcp_event_t){"current", (uint8_t)(a->opt.period_us / 10), 4, 2};
    a->events[1] = (p2d_xcp_event_t){"speed", (uint8_t)(a->opt.period_us * a->opt.speed_divider / 100), 5, 1};
    c.segments = a->segments;
    c.segment_count = 3;
    c.shadow = &a->shadow;
    c.shadow_bytes = sizeof a->shadow;
    c.events = a->events;
    c.event_count = 2;
    c.daq_memory = a->daq_memory;
    c.daq_memory_bytes = sizeof a->daq_memory;
    c.queue = a->queue;
    c.queue_bytes = (uint32_t)a->opt.queue_bytes;
    c.max_cto = (uint8_t)a->opt.max_cto;
    c.max_dto = (uint16_t)a->opt.max_dto;
    c.timestamp_unit = 3; /* 1 us */
    c.timestamp_ticks = 1;
    c.link_timeout_ticks = (uint32_t)(a->opt.link_timeout_ms * 1000L);
    c.protected_resources = a->opt.protect ? (P2D_XCP_RESOURCE_CALPAG | P2D_XCP_RESOURCE_DAQ) : 0u;
    c.seed_bytes = 4;
    c.id = "pmsm2dof xcp_tcp_slave";
    c.a2l_name = "xcp_tcp_slave";
    c.user = a;
    c.clock = clock_us;
    c.commit = commit;
    c.key = key;
    c.lock = app_lock;
    c.unlock = app_unlock;
    status = p2d_xcp_init(&a->xcp, &c);
    if (status != P2D_XCP_OK) {
        fprintf(stderr, "xcp_tcp_slave: %s must be %s\n", p2d_xcp_status_param(status), p2d_xcp_status_range(status));
        return -1;
    }
    g.Ts_s = 1e-6f * (float)(a->opt.period_us * a->opt.speed_divider);
    g.ramp_radps_per_s = a->opt.ramp_radps_per_s;
    g.hold_s = a->opt.hold_s;
    status = p2d_xcp_guard_init(&a->guard, &g);
    if (status != P2D_XCP_OK) {
        fprintf(stderr, "xcp_tcp_slave: %s must be %s\n", p2d_xcp_status_param(status), p2d_xcp_status_range(status));
        return -1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    static app_t a;
    struct sockaddr_in address;
    socklen_t address_bytes = sizeof address;
    pthread_t thread;
    int listener, one = 1;
    long deadline_s;
    a.opt.port = (int)option(argc, argv, "--port", 0);
    a.opt.period_us = option(argc, argv, "--period-us", 500);
    a.opt.speed_divider = (int)option(argc, argv, "--speed-divider", 4);
    a.opt.link_timeout_ms = option(argc, argv, "--link-timeout-ms", 0);
    a.opt.ramp_radps_per_s = option_float(argc, argv, "--ramp-radps-per-s", 1000.0f);
    a.opt.hold_s = option_float(argc, argv, "--hold-s", 0.05f);
    a.opt.max_cto = (int)option(argc, argv, "--max-cto", 255);
    a.opt.max_dto = (int)option(argc, argv, "--max-dto", 1024);
    a.opt.queue_bytes = option(argc, argv, "--queue-bytes", 65536);
    a.opt.lifetime_s = option(argc, argv, "--lifetime-s", 60);
    for (int i = 1; i < argc; ++i) a.opt.protect |= strcmp(argv[i], "--protect") == 0;
    if (a.opt.period_us < 100 || a.opt.period_us > 2550 || a.opt.speed_divider < 1 || a.opt.speed_divider > 100 ||
        a.opt.period_us * a.opt.speed_divider > 25500 || a.opt.link_timeout_ms < 0 || a.opt.queue_bytes < 16 ||
        a.opt.queue_bytes > (1L << 24) || a.opt.lifetime_s < 1 || a.opt.lifetime_s > 3600 || a.opt.max_cto < 0 ||
        a.opt.max_cto > 255 || a.opt.max_dto < 0 || a.opt.max_dto > 65531) {
        fprintf(stderr, "xcp_tcp_slave: an option is out of range (see the file's comment)\n");
        return 2;
    }
    a.queue = malloc((size_t)a.opt.queue_bytes);
    if (a.queue == NULL) return 2;
    clock_gettime(CLOCK_MONOTONIC, &a.start);
    pthread_mutex_init(&a.mutex, NULL);
    a.cal = (drive_cal_t){0.0f, 0.05f, 500.0f};
    if (configure(&a) != 0) return 2;

    signal(SIGPIPE, SIG_IGN);
    listener = socket(AF_INET, SOCK_STREAM, 0);
    setsockopt(listener, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    memset(&address, 0, sizeof address);
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = htons((uint16_t)a.opt.port);
    if (listener < 0 || bind(listener, (struct sockaddr *)&address, sizeof address) != 0 || listen(listener, 1) != 0 ||
        getsockname(listener, (struct sockaddr *)&address, &address_bytes) != 0) {
        perror("xcp_tcp_slave: listen on 127.0.0.1");
        return 1;
    }
    printf("port %d\n", ntohs(address.sin_port));
    fflush(stdout);
    pthread_create(&thread, NULL, interrupts, &a);
    deadline_s = (long)time(NULL) + a.opt.lifetime_s;
    while (time(NULL) < deadline_s) {
        struct pollfd p = {listener, POLLIN, 0};
        int fd;
        if (poll(&p, 1, 100) <= 0) continue;
        fd = accept(listener, NULL, NULL);
        if (fd < 0) continue;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        serve(&a, fd, deadline_s);
        close(fd);
    }
    a.stop = 1;
    pthread_join(thread, NULL);
    close(listener);
    free(a.queue);
    return 0;
}
