/*
 * pmsm2dof fuzzing: the XCP slave (xcp.h) fed packet sequences.
 *
 * Invariant: no sequence reads or writes memory outside the declared
 * segments. Each segment lives in its own allocation between two guard
 * blocks, which AddressSanitizer poisons (a read or write there aborts at
 * once) and whose bytes are checked after every operation; the DAQ memory
 * and the DTO queue are allocations of exactly their declared sizes. Besides:
 * measurement segments never change; a calibration segment changes only when
 * the commit callback accepts a page, and then to exactly that page; a page
 * differs from the segment in at most one run of max_cto - 2 bytes (one
 * DOWNLOAD); every packet handed out fits max_cto or max_dto; the lock is
 * balanced and never nested.
 *
 * Input: 8 configuration bytes (max_cto, max_dto, queue and DAQ memory sizes,
 * protection, framing checksum), then operations, op % 8:
 *   0, 1  a command: length byte, that many bytes (the packet)
 *   2     a command whose address field (SET_MTA, SHORT_UPLOAD, WRITE_DAQ: bytes 4..7) is replaced by
 *         segment[b4 % 3].address + (int8)b5: near the segments' edges
 *   3     bytes on the byte stream: length byte, that many bytes, through the framing receiver
 *   4     an event: byte (event number % 3: the two events and one that does not exist)
 *   5     the speed sample's calibration commit: byte (bit 0: the callback accepts)
 *   6     the transport takes every packet waiting
 *   7     the clock moves on: 2 bytes [ticks], then the link watchdog is read
 */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pmsm2dof/xcp.h"

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define FZ_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define FZ_ASAN 1
#endif
#ifdef FZ_ASAN
#include <sanitizer/asan_interface.h>
#define FZ_POISON(p, n) __asan_poison_memory_region((p), (n))
#define FZ_UNPOISON(p, n) __asan_unpoison_memory_region((p), (n))
#else
#define FZ_POISON(p, n) ((void)(p), (void)(n))
#define FZ_UNPOISON(p, n) ((void)(p), (void)(n))
#endif

#define FZ_REQUIRE(cond, ...)                                                                                \
    do {                                                                                                     \
        if (!(cond)) {                                                                                       \
            fprintf(stderr, "pmsm2dof fuzz invariant violated at %s:%d: %s\n  ", __FILE__, __LINE__, #cond); \
            fprintf(stderr, __VA_ARGS__);                                                                    \
            fputc('\n', stderr);                                                                             \
            abort();                                                                                         \
        }                                                                                                    \
    } while (0)

#define GUARD_BYTES 64u
#define GUARD_VALUE 0xA5u
#define SEGMENTS 3

/* measurement [0x1000, 0x1028), calibration [0x1028, 0x1034) right after it, measurement at the top */
static const uint32_t SEGMENT_ADDRESS[SEGMENTS] = {0x1000u, 0x1028u, 0xFFFFFFF8u};
static const uint32_t SEGMENT_BYTES[SEGMENTS] = {40u, 12u, 8u};
static const p2d_xcp_access_t SEGMENT_ACCESS[SEGMENTS] = {P2D_XCP_MEASUREMENT, P2D_XCP_CALIBRATION,
                                                          P2D_XCP_MEASUREMENT};

typedef struct {
    const uint8_t *data;
    size_t size;
} fz_reader_t;

static uint8_t fz_u8(fz_reader_t *r)
{
    uint8_t b = 0;
    if (r->size > 0) {
        b = r->data[0];
        r->data++;
        r->size--;
    }
    return b;
}

typedef struct {
    uint8_t *block[SEGMENTS];     /* guard | segment | guard */
    uint8_t expect[SEGMENTS][40]; /* what each segment must hold */
    p2d_xcp_segment_t segments[SEGMENTS];
    p2d_xcp_event_t events[2];
    uint8_t shadow[12];
    uint8_t *daq_memory;
    uint8_t *queue;
    p2d_xcp_t x;
    p2d_xcp_frame_t link;
    uint32_t now;
    int32_t verdict;
    int depth, depth_max;
    bool accepted; /* the last commit call accepted */
    uint8_t max_cto;
} fz_rig_t;

static uint32_t fz_clock(void *user) { return ((fz_rig_t *)user)->now; }

static void fz_lock(void *user)
{
    fz_rig_t *r = (fz_rig_t *)user;
    if (++r->depth > r->depth_max) r->depth_max = r->depth;
}

static void fz_unlock(void *user) { ((fz_rig_t *)user)->depth--; }

static int32_t fz_commit(void *user, uint16_t segment, const void *page)
{
    fz_rig_t *r = (fz_rig_t *)user;
    const uint8_t *p = (const uint8_t *)page, *now;
    uint32_t first = UINT32_MAX, last = 0;
    FZ_REQUIRE(segment < SEGMENTS && SEGMENT_ACCESS[segment] == P2D_XCP_CALIBRATION, "commit of segment %u",
               (unsigned)segment);
    now = r->block[segment] + GUARD_BYTES;
    for (uint32_t i = 0; i < SEGMENT_BYTES[segment]; ++i) {
        if (p[i] != now[i]) {
            if (first == UINT32_MAX) first = i;
            last = i;
        }
    }
    FZ_REQUIRE(first == UINT32_MAX || last - first + 1u <= (uint32_t)r->max_cto - 2u,
               "the page differs in bytes %u..%u: more than one DOWNLOAD", (unsigned)first, (unsigned)last);
    r->accepted = r->verdict == 0;
    if (r->accepted) memcpy(r->expect[segment], p, SEGMENT_BYTES[segment]);
    return r->verdict;
}

/* the key: one byte, 0 (so that the fuzzer can unlock) */
static uint8_t fz_key(void *user, uint8_t resource, const uint8_t *seed, uint8_t seed_bytes, uint8_t *key)
{
    (void)user;
    (void)resource;
    (void)seed;
    FZ_REQUIRE(seed_bytes >= 1u && seed_bytes <= P2D_XCP_KEY_MAX_BYTES, "seed of %u bytes", (unsigned)seed_bytes);
    key[0] = 0;
    return 1;
}

static void fz_check(fz_rig_t *r)
{
    for (int s = 0; s < SEGMENTS; ++s) {
        uint8_t *b = r->block[s];
        uint32_t n = SEGMENT_BYTES[s];
        FZ_UNPOISON(b, GUARD_BYTES);
        FZ_UNPOISON(b + GUARD_BYTES + n, GUARD_BYTES);
        for (uint32_t i = 0; i < GUARD_BYTES; ++i) {
            FZ_REQUIRE(b[i] == GUARD_VALUE && b[GUARD_BYTES + n + i] == GUARD_VALUE, "guard of segment %d written", s);
        }
        FZ_POISON(b, GUARD_BYTES);
        FZ_POISON(b + GUARD_BYTES + n, GUARD_BYTES);
        FZ_REQUIRE(memcmp(b + GUARD_BYTES, r->expect[s], n) == 0, "segment %d changed outside an accepted commit", s);
    }
    FZ_REQUIRE(r->depth == 0 && r->depth_max <= 1, "lock depth %d, deepest %d", r->depth, r->depth_max);
    FZ_REQUIRE(r->x.queue_used <= r->x.config.queue_bytes && r->x.daq_used_bytes <= r->x.config.daq_memory_bytes,
               "queue %u of %u, DAQ memory %u of %u", (unsigned)r->x.queue_used, (unsigned)r->x.config.queue_bytes,
               (unsigned)r->x.daq_used_bytes, (unsigned)r->x.config.daq_memory_bytes);
}

static void fz_take_all(fz_rig_t *r)
{
    uint8_t packet[P2D_XCP_FRAME_HEADER_BYTES + 65536];
    size_t limit = r->x.config.max_cto > r->x.config.max_dto ? r->x.config.max_cto : r->x.config.max_dto, n;
    for (int i = 0; i < 4096 && (n = p2d_xcp_take(&r->x, packet + P2D_XCP_FRAME_HEADER_BYTES, limit)) > 0; ++i) {
        FZ_REQUIRE(n <= limit, "a packet of %zu bytes", n);
        if (packet[P2D_XCP_FRAME_HEADER_BYTES] >= 0xFCu) {
            FZ_REQUIRE(n <= r->x.config.max_cto, "a response of %zu bytes", n);
        }
        FZ_REQUIRE(p2d_xcp_frame_tx(&r->link, packet, n) == n + P2D_XCP_FRAME_HEADER_BYTES + r->link.checksum,
                   "frame length");
    }
}

static void fz_command(fz_rig_t *r, fz_reader_t *in, bool near_segments)
{
    uint8_t packet[256];
    size_t len = fz_u8(in);
    for (size_t i = 0; i < len; ++i) packet[i] = fz_u8(in);
    if (near_segments && len >= 8u && (packet[0] == 0xF6u || packet[0] == 0xF4u || packet[0] == 0xE1u)) {
        uint32_t address = SEGMENT_ADDRESS[packet[4] % SEGMENTS] + (uint32_t)(int32_t)(int8_t)packet[5];
        memcpy(packet + 4, &address, 4);
    }
    p2d_xcp_command(&r->x, packet, len);
}

static void fz_stream(fz_rig_t *r, fz_reader_t *in)
{
    size_t len = fz_u8(in), n;
    for (size_t i = 0; i < len; ++i) {
        n = p2d_xcp_frame_rx(&r->link, fz_u8(in));
        FZ_REQUIRE(n <= sizeof r->link.packet, "a received packet of %zu bytes", n);
        if (n > 0u) p2d_xcp_command(&r->x, r->link.packet, n);
    }
}

static bool fz_setup(fz_rig_t *r, fz_reader_t *in)
{
    p2d_xcp_config_t c;
    uint8_t cto = fz_u8(in), dto = fz_u8(in), queue = fz_u8(in), daq = fz_u8(in), options = fz_u8(in);
    uint8_t seed = fz_u8(in);
    (void)fz_u8(in);
    (void)fz_u8(in);
    memset(r, 0, sizeof *r);
    for (int s = 0; s < SEGMENTS; ++s) {
        uint32_t n = SEGMENT_BYTES[s];
        r->block[s] = (uint8_t *)malloc(2u * GUARD_BYTES + n);
        FZ_REQUIRE(r->block[s] != NULL, "malloc");
        memset(r->block[s], GUARD_VALUE, 2u * GUARD_BYTES + n);
        for (uint32_t i = 0; i < n; ++i) r->block[s][GUARD_BYTES + i] = (uint8_t)(17u * (uint32_t)s + 3u * i);
        memcpy(r->expect[s], r->block[s] + GUARD_BYTES, n);
        FZ_POISON(r->block[s], GUARD_BYTES);
        FZ_POISON(r->block[s] + GUARD_BYTES + n, GUARD_BYTES);
        r->segments[s] =
            (p2d_xcp_segment_t){SEGMENT_ADDRESS[s], r->block[s] + GUARD_BYTES, SEGMENT_BYTES[s], SEGMENT_ACCESS[s]};
    }
    r->events[0] = (p2d_xcp_event_t){"current", 50, 3, 1};
    r->events[1] = (p2d_xcp_event_t){"speed", 5, 5, 0};
    memset(&c, 0, sizeof c);
    c.segments = r->segments;
    c.segment_count = SEGMENTS;
    c.shadow = r->shadow;
    c.shadow_bytes = sizeof r->shadow;
    c.events = r->events;
    c.event_count = 2;
    c.max_cto = (uint8_t)(8u + cto % 248u);
    c.max_dto = (uint16_t)(8u + (uint32_t)dto * 2u);
    c.queue_bytes = (uint32_t)c.max_dto + 2u + (uint32_t)queue * 4u;
    c.daq_memory_bytes = 1u + (uint32_t)daq * 8u;
    r->queue = (uint8_t *)malloc(c.queue_bytes);
    r->daq_memory = (uint8_t *)malloc(c.daq_memory_bytes);
    FZ_REQUIRE(r->queue != NULL && r->daq_memory != NULL, "malloc");
    c.queue = r->queue;
    c.daq_memory = r->daq_memory;
    c.timestamp_unit = 3;
    c.timestamp_ticks = 1;
    c.link_timeout_ticks = 1000;
    c.protected_resources =
        (uint8_t)(((options & 1u) ? P2D_XCP_RESOURCE_CALPAG : 0u) | ((options & 2u) ? P2D_XCP_RESOURCE_DAQ : 0u));
    c.seed_bytes = (uint8_t)(1u + seed % (c.max_cto - 2u < 32u ? c.max_cto - 2u : 32u));
    c.id = "fuzz";
    c.a2l_name = (options & 4u) ? "fuzz_a2l" : NULL;
    c.user = r;
    c.clock = fz_clock;
    c.commit = fz_commit;
    c.key = fz_key;
    c.lock = fz_lock;
    c.unlock = fz_unlock;
    r->max_cto = c.max_cto;
    p2d_xcp_frame_init(&r->link, (options & 8u) != 0u);
    FZ_REQUIRE(p2d_xcp_init(&r->x, &c) == P2D_XCP_OK, "a valid configuration refused");
    return true;
}

static void fz_teardown(fz_rig_t *r)
{
    for (int s = 0; s < SEGMENTS; ++s) {
        FZ_UNPOISON(r->block[s], 2u * GUARD_BYTES + SEGMENT_BYTES[s]);
        free(r->block[s]);
    }
    free(r->queue);
    free(r->daq_memory);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static fz_rig_t rig;
    fz_reader_t in = {data, size};
    fz_rig_t *r = &rig;
    fz_setup(r, &in);
    while (in.size > 0) {
        uint8_t op = fz_u8(&in);
        switch (op % 8u) {
        case 0:
        case 1: fz_command(r, &in, false); break;
        case 2: fz_command(r, &in, true); break;
        case 3: fz_stream(r, &in); break;
        case 4: p2d_xcp_event(&r->x, (uint16_t)(fz_u8(&in) % 3u)); break;
        case 5: {
            p2d_xcp_commit_t result;
            r->verdict = (fz_u8(&in) & 1u) ? 0 : 7;
            r->accepted = false;
            result = p2d_xcp_calibrate(&r->x);
            FZ_REQUIRE(result != P2D_XCP_COMMIT_APPLIED || r->accepted, "applied what the callback rejected");
            break;
        }
        case 6: fz_take_all(r); break;
        default: {
            uint32_t ticks = fz_u8(&in);
            ticks |= (uint32_t)fz_u8(&in) << 8;
            r->now += ticks;
            (void)p2d_xcp_link_check(&r->x);
            break;
        }
        }
        fz_check(r);
    }
    fz_take_all(r);
    fz_check(r);
    fz_teardown(r);
    return 0;
}
