/*
 * The virtual board's machine on the PC: the control interrupt is a call (the
 * background loop's wait runs the next one), the trace goes to trace.bin in
 * the working folder, the diagnostics to stderr, the arguments name=N come from
 * the environment variable P2D_VIRTUAL_DRIVE_ARGS. The same foc.c and
 * board_virtual.c as on the MCU; the firmware's time and cost are not modelled
 * (no cost.bin).
 *
 * The link (argument link=1): the XCP master connects by TCP to 127.0.0.1 on
 * port=N (0: a free port), one master at a time; the drive writes "port N" on
 * stdout once it listens, and ends when its standard input closes (the program
 * that started it is gone). Time: with realtime=1 (the default) the control
 * interrupt comes every Ts of the wall clock (CLOCK_MONOTONIC deadlines; a late
 * period runs at once), and a byte from the master wakes the background loop
 * as a UART interrupt would. With realtime=0 the drive runs as fast as the PC
 * allows, paced by the link: it waits while the socket takes no more bytes (no
 * DAQ packet is dropped), and while the master has been silent for half the
 * link timeout (timeout_ms) of the drive's time it waits for the master's next
 * byte, at most the timeout of the wall clock; so a master that talks at least
 * every half timeout of its own time never trips the watchdog however fast the
 * drive runs, and a silent one does.
 */
#define _GNU_SOURCE /* ppoll: waits shorter than a millisecond */

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "virtual_target.h"

static FILE *trace;            /* the trace output */
static bool started;           /* the control interrupt runs */
static int listener = -1;      /* the link's listening socket (link=1) */
static int client = -1;        /* the connected master, or -1 */
static bool realtime;          /* the control interrupt on the wall clock */
static bool tx_blocked;        /* the socket took less than it was given */
static int64_t Ts_ns;          /* period of the control interrupt [ns] */
static int64_t deadline_ns;    /* wall-clock time of the next control interrupt [ns] */
static uint64_t periods;       /* control interrupts run [-] */
static uint64_t rx_period;     /* the period of the master's last byte [-] */
static uint64_t ahead_periods; /* fast: periods run past the master's last byte before waiting for it [-] */
static int timeout_ms;         /* fast: longest wait for the master [ms] */

static int64_t now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

static void fail(const char *what)
{
    fprintf(stderr, "virtual drive: %s (%s)\n", what, strerror(errno));
    exit(1);
}

/* Listen on 127.0.0.1:port and tell the port on stdout. */
static void listen_link(uint16_t port)
{
    struct sockaddr_in address;
    socklen_t bytes = sizeof address;
    int one = 1;
    signal(SIGPIPE, SIG_IGN);
    listener = socket(AF_INET, SOCK_STREAM, 0);
    if (listener < 0) fail("cannot open a socket");
    setsockopt(listener, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    memset(&address, 0, sizeof address);
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = htons(port);
    if (bind(listener, (struct sockaddr *)&address, sizeof address) != 0 || listen(listener, 1) != 0 ||
        getsockname(listener, (struct sockaddr *)&address, &bytes) != 0) {
        fail("cannot listen on 127.0.0.1 (port=N)");
    }
    printf("port %u\n", (unsigned)ntohs(address.sin_port));
    fflush(stdout);
}

void vt_init(void)
{
    trace = fopen("trace.bin", "wb");
    if (trace == NULL) {
        fprintf(stderr, "virtual drive: cannot create trace.bin\n");
        exit(1);
    }
    if (vt_argument("link", 0u) != 0u) {
        uint64_t port = vt_argument("port", 0u);
        if (port > 65535u) {
            fprintf(stderr, "virtual drive: port=%llu is not a TCP port (0..65535)\n", (unsigned long long)port);
            exit(1);
        }
        realtime = vt_argument("realtime", 1u) != 0u;
        timeout_ms = (int)vt_argument("timeout_ms", 200u);
        listen_link((uint16_t)port);
    }
}

uint64_t vt_argument(const char *name, uint64_t fallback)
{
    const char *args = getenv("P2D_VIRTUAL_DRIVE_ARGS");
    size_t len = strlen(name);
    for (const char *p = args; p != NULL && *p != '\0'; ++p) {
        if ((p == args || p[-1] == ' ') && strncmp(p, name, len) == 0 && p[len] == '=') {
            return strtoull(p + len + 1, NULL, 10);
        }
    }
    return fallback;
}

void vt_start_interrupt(float Ts_s)
{
    Ts_ns = (int64_t)((double)Ts_s * 1e9 + 0.5);
    ahead_periods = (uint64_t)((double)timeout_ms * 1e6 / 2.0 / (double)Ts_ns);
    deadline_ns = now_ns() + Ts_ns;
    started = true;
}

bool vt_hold(bool hold)
{
    (void)hold;
    return false;
}

uint32_t vt_clock(void) { return 0u; }

uint32_t vt_instructions(uint32_t clock_start, uint32_t clock_end)
{
    (void)clock_start;
    (void)clock_end;
    return 0u;
}

/* Take a waiting master (one at a time). */
static void accept_master(void)
{
    int one = 1;
    struct pollfd p = {listener, POLLIN, 0};
    if (client >= 0 || poll(&p, 1, 0) <= 0) return;
    client = accept(listener, NULL, NULL);
    if (client < 0) return;
    setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    rx_period = periods;
    tx_blocked = false;
}

static void drop_master(void)
{
    close(client);
    client = -1;
    tx_blocked = false;
}

/* Wait up to wait_ns for: the master's bytes (POLLIN), room to send (POLLOUT), a master, or the end of stdin. */
static void wait_link(int64_t wait_ns, short events)
{
    struct pollfd p[2] = {{client >= 0 ? client : listener, client >= 0 ? events : POLLIN, 0}, {0, POLLIN, 0}};
    struct timespec t = {(time_t)(wait_ns / 1000000000), (long)(wait_ns % 1000000000)};
    if (wait_ns < 0) t.tv_sec = t.tv_nsec = 0;
    if (ppoll(p, 2, &t, NULL) > 0 && (p[1].revents & (POLLIN | POLLHUP)) != 0) {
        char c;
        if (read(0, &c, 1) <= 0) exit(0); /* whoever started the drive is gone */
    }
}

void vt_wait(void)
{
    if (!started) {
        fprintf(stderr, "virtual drive: waiting with no control interrupt started\n");
        exit(1);
    }
    if (listener >= 0) {
        accept_master();
        if (realtime) {
            /* the background loop wakes at the master's bytes, as at a UART interrupt */
            int64_t left = deadline_ns - now_ns();
            if (left > 0) {
                wait_link(left, POLLIN);
                if (now_ns() < deadline_ns) return;
            }
            deadline_ns += Ts_ns;
        } else {
            if (client >= 0 && tx_blocked) wait_link((int64_t)timeout_ms * 1000000, POLLOUT);
            tx_blocked = false;
            if (client >= 0 && periods - rx_period > ahead_periods) {
                wait_link((int64_t)timeout_ms * 1000000, POLLIN);
                rx_period = periods; /* one wait per half timeout of silence */
            } else if (client < 0) {
                wait_link(1000000, POLLIN); /* no master yet: idle at most a period per millisecond */
            }
        }
    }
    periods++;
    board_virtual_interrupt();
}

uint32_t vt_link_receive(uint8_t *bytes, uint32_t capacity)
{
    ssize_t got;
    if (client < 0) return 0u;
    got = recv(client, bytes, capacity, MSG_DONTWAIT);
    if (got == 0 || (got < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
        drop_master();
        return 0u;
    }
    if (got < 0) return 0u;
    rx_period = periods;
    return (uint32_t)got;
}

uint32_t vt_link_send(const uint8_t *bytes, uint32_t n)
{
    ssize_t sent;
    if (client < 0) return n; /* no master: the bytes go nowhere, as on an unconnected UART */
    sent = send(client, bytes, n, MSG_DONTWAIT | MSG_NOSIGNAL);
    if (sent < 0) {
        if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) drop_master();
        tx_blocked = true;
        return 0u;
    }
    if ((uint32_t)sent < n) tx_blocked = true;
    return (uint32_t)sent;
}

void vt_lock(bool enter) { (void)enter; }

void vt_write(vt_stream_t stream, const void *bytes, uint32_t n)
{
    if (stream != VT_TRACE) return; /* no cost runs on the PC */
    if (fwrite(bytes, 1, n, trace) != n) {
        fprintf(stderr, "virtual drive: writing trace.bin failed\n");
        exit(1);
    }
}

void vt_report(const char *text) { fprintf(stderr, "%s\n", text); }

void vt_exit(bool ok)
{
    if (fclose(trace) != 0) ok = false;
    if (client >= 0) close(client);
    if (listener >= 0) close(listener);
    exit(ok ? 0 : 1);
}
