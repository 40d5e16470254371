/*
 * Tests of the XCP slave (xcp.h) against packets written out by hand from the
 * ASAM XCP 1.x protocol layer: the expected bytes of every response and DTO are
 * spelled out here, independently of xcp.c.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "pmsm2dof/xcp.h"

/* XCP codes, as the standard numbers them */
#define RES 0xFF
#define ERR 0xFE
#define ERR_CMD_SYNCH 0x00
#define ERR_CMD_BUSY 0x10
#define ERR_DAQ_ACTIVE 0x11
#define ERR_CMD_UNKNOWN 0x20
#define ERR_CMD_SYNTAX 0x21
#define ERR_OUT_OF_RANGE 0x22
#define ERR_WRITE_PROTECTED 0x23
#define ERR_ACCESS_DENIED 0x24
#define ERR_ACCESS_LOCKED 0x25
#define ERR_SEQUENCE 0x29
#define ERR_DAQ_CONFIG 0x2A
#define ERR_MEMORY_OVERFLOW 0x30

#define MEAS_ADDRESS 0x1000u
#define CAL_ADDRESS 0x2000u
#define TOP_ADDRESS 0xFFFFFFF0u

typedef struct {
    float gain;   /* [-] */
    float offset; /* [rad/s] */
} cal_t;

typedef struct {
    uint32_t now;       /* the clock [ticks] */
    int32_t verdict;    /* what the commit callback answers */
    int commits;        /* calls of the commit callback */
    uint16_t segment;   /* its last segment */
    cal_t page;         /* its last page */
    int depth;          /* lock depth now */
    int depth_max;      /* deepest lock */
    int locks;          /* lock calls */
    uint8_t meas[32];   /* measurement segment */
    cal_t cal;          /* calibration segment */
    uint8_t top[16];    /* measurement segment at the top of the address space */
    cal_t shadow;       /* shadow page */
    uint8_t daq[512];   /* DAQ memory */
    uint8_t queue[128]; /* DTO queue */
    p2d_xcp_segment_t segments[3];
    p2d_xcp_event_t events[2];
    p2d_xcp_config_t cfg;
    p2d_xcp_t x;
    uint8_t out[300]; /* the last packet taken */
    size_t out_len;
} rig_t;

static uint32_t rig_clock(void *user) { return ((rig_t *)user)->now; }

static int32_t rig_commit(void *user, uint16_t segment, const void *page)
{
    rig_t *r = (rig_t *)user;
    r->commits++;
    r->segment = segment;
    memcpy(&r->page, page, sizeof r->page);
    return r->verdict;
}

/* the test's key: every seed byte xor 0x5A, then its complement: twice the seed's length */
static uint8_t rig_key(void *user, uint8_t resource, const uint8_t *seed, uint8_t seed_bytes, uint8_t *key)
{
    (void)user;
    (void)resource;
    for (uint8_t i = 0; i < seed_bytes; ++i) {
        key[i] = (uint8_t)(seed[i] ^ 0x5Au);
        key[seed_bytes + i] = (uint8_t)~seed[i];
    }
    return (uint8_t)(2u * seed_bytes);
}

static void rig_lock(void *user)
{
    rig_t *r = (rig_t *)user;
    r->locks++;
    if (++r->depth > r->depth_max) r->depth_max = r->depth;
}

static void rig_unlock(void *user) { ((rig_t *)user)->depth--; }

/* A slave with max_cto 8 (CAN-sized), max_dto 16, a measurement, a calibration and a top segment, two events. */
static void rig_config(rig_t *r)
{
    memset(r, 0, sizeof *r);
    for (int i = 0; i < 32; ++i) r->meas[i] = (uint8_t)(0x10 + i);
    for (int i = 0; i < 16; ++i) r->top[i] = (uint8_t)(0xA0 + i);
    r->cal.gain = 2.0f;
    r->cal.offset = -1.0f;
    r->segments[0] = (p2d_xcp_segment_t){MEAS_ADDRESS, r->meas, sizeof r->meas, P2D_XCP_MEASUREMENT};
    r->segments[1] = (p2d_xcp_segment_t){CAL_ADDRESS, &r->cal, sizeof r->cal, P2D_XCP_CALIBRATION};
    r->segments[2] = (p2d_xcp_segment_t){TOP_ADDRESS, r->top, sizeof r->top, P2D_XCP_MEASUREMENT};
    r->events[0] = (p2d_xcp_event_t){"current", 50, 3, 2};
    r->events[1] = (p2d_xcp_event_t){"speed", 50, 4, 1};
    r->cfg = (p2d_xcp_config_t){0};
    r->cfg.segments = r->segments;
    r->cfg.segment_count = 3;
    r->cfg.shadow = &r->shadow;
    r->cfg.shadow_bytes = sizeof r->shadow;
    r->cfg.events = r->events;
    r->cfg.event_count = 2;
    r->cfg.daq_memory = r->daq;
    r->cfg.daq_memory_bytes = sizeof r->daq;
    r->cfg.queue = r->queue;
    r->cfg.queue_bytes = sizeof r->queue;
    r->cfg.max_cto = 8;
    r->cfg.max_dto = 16;
    r->cfg.timestamp_unit = 3;
    r->cfg.timestamp_ticks = 1;
    r->cfg.link_timeout_ticks = 100;
    r->cfg.seed_bytes = 6;
    r->cfg.id = "pmsm2dof test";
    r->cfg.user = r;
    r->cfg.clock = rig_clock;
    r->cfg.commit = rig_commit;
    r->cfg.key = rig_key;
    r->cfg.lock = rig_lock;
    r->cfg.unlock = rig_unlock;
}

static void rig_init(rig_t *r)
{
    rig_config(r);
    CHECK(p2d_xcp_init(&r->x, &r->cfg) == P2D_XCP_OK);
}

/* send a command, take the next packet into r->out; returns its length (0: none) */
static size_t cmd(rig_t *r, const uint8_t *packet, size_t len)
{
    p2d_xcp_command(&r->x, packet, len);
    r->out_len = p2d_xcp_take(&r->x, r->out, sizeof r->out);
    return r->out_len;
}

#define CMD(r, ...)                              \
    do {                                         \
        const uint8_t packet_[] = {__VA_ARGS__}; \
        (void)cmd((r), packet_, sizeof packet_); \
    } while (0)

static size_t take(rig_t *r)
{
    r->out_len = p2d_xcp_take(&r->x, r->out, sizeof r->out);
    return r->out_len;
}

static int out_is(const rig_t *r, const uint8_t *bytes, size_t n)
{
    return r->out_len == n && memcmp(r->out, bytes, n) == 0;
}

#define OUT_IS(r, ...)                                                                                    \
    do {                                                                                                  \
        const uint8_t expect_[] = {__VA_ARGS__};                                                          \
        check_record(out_is((r), expect_, sizeof expect_), "response " #__VA_ARGS__, __FILE__, __LINE__); \
    } while (0)

static void put32le(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i) p[i] = (uint8_t)(v >> (8 * i));
}

/* SET_MTA to an address (this host is little endian: the slave's byte order, checked in test_connect) */
static void set_mta(rig_t *r, uint32_t address)
{
    uint8_t p[8] = {0xF6, 0, 0, 0};
    put32le(p + 4, address);
    cmd(r, p, sizeof p);
}

static void test_init_validation(void)
{
    rig_t r;
    p2d_xcp_t before;
    p2d_xcp_segment_t overlap[2], top_overflow;
    p2d_xcp_event_t unnamed = {NULL, 1, 3, 0}, empty = {"", 1, 3, 0}, bad_unit = {"e", 1, 10, 0};
    char long_text[300];
    memset(long_text, 'a', sizeof long_text - 1);
    long_text[sizeof long_text - 1] = '\0';

#define REJECTS(field_change, code)                       \
    do {                                                  \
        rig_config(&r);                                   \
        field_change;                                     \
        memset(&r.x, 0xA5, sizeof r.x);                   \
        memcpy(&before, &r.x, sizeof before);             \
        CHECK(p2d_xcp_init(&r.x, &r.cfg) == (code));      \
        CHECK(memcmp(&before, &r.x, sizeof before) == 0); \
    } while (0)

    rig_config(&r);
    CHECK(p2d_xcp_init(NULL, &r.cfg) == P2D_XCP_ERR_NULL);
    CHECK(p2d_xcp_init(&r.x, NULL) == P2D_XCP_ERR_NULL);
    REJECTS(r.cfg.segments = NULL, P2D_XCP_ERR_SEGMENTS);
    REJECTS(r.cfg.segment_count = 0, P2D_XCP_ERR_SEGMENTS);
    REJECTS(r.segments[0].memory = NULL, P2D_XCP_ERR_SEGMENT_MEMORY);
    REJECTS(r.segments[0].size_bytes = 0, P2D_XCP_ERR_SEGMENT_SIZE);
    top_overflow = (p2d_xcp_segment_t){0xFFFFFFF0u, r.top, 17, P2D_XCP_MEASUREMENT};
    REJECTS(r.segments[2] = top_overflow, P2D_XCP_ERR_SEGMENT_SIZE);
    REJECTS(r.segments[0].access = (p2d_xcp_access_t)2, P2D_XCP_ERR_SEGMENT_ACCESS);
    /* the calibration segment starts on the last byte of the measurement segment */
    REJECTS(r.segments[1].address = MEAS_ADDRESS + 31u, P2D_XCP_ERR_SEGMENT_OVERLAP);
    REJECTS(r.segments[0].address = CAL_ADDRESS - 31u, P2D_XCP_ERR_SEGMENT_OVERLAP);
    overlap[0] = (p2d_xcp_segment_t){0x100u, r.meas, 4, P2D_XCP_MEASUREMENT};
    overlap[1] = (p2d_xcp_segment_t){0x0FEu, r.meas, 8, P2D_XCP_MEASUREMENT}; /* covers the other whole */
    REJECTS((r.cfg.segments = overlap, r.cfg.segment_count = 2), P2D_XCP_ERR_SEGMENT_OVERLAP);
    REJECTS(r.cfg.shadow = NULL, P2D_XCP_ERR_SHADOW);
    REJECTS(r.cfg.shadow_bytes = sizeof(cal_t) - 1u, P2D_XCP_ERR_SHADOW);
    REJECTS(r.cfg.commit = NULL, P2D_XCP_ERR_COMMIT);
    REJECTS(r.cfg.events = NULL, P2D_XCP_ERR_EVENTS);
    REJECTS(r.events[1] = unnamed, P2D_XCP_ERR_EVENT_NAME);
    REJECTS(r.events[1] = empty, P2D_XCP_ERR_EVENT_NAME);
    REJECTS(r.events[0].name = long_text, P2D_XCP_ERR_EVENT_NAME);
    REJECTS(r.events[0] = bad_unit, P2D_XCP_ERR_EVENT_CYCLE_UNIT);
    REJECTS(r.cfg.daq_memory = NULL, P2D_XCP_ERR_DAQ_MEMORY);
    REJECTS(r.cfg.queue_bytes = 17, P2D_XCP_ERR_QUEUE); /* max_dto 16 + 2 */
    REJECTS(r.cfg.max_cto = 7, P2D_XCP_ERR_MAX_CTO);
    REJECTS(r.cfg.max_dto = 7, P2D_XCP_ERR_MAX_DTO);
    REJECTS(r.cfg.max_dto = 65532, P2D_XCP_ERR_MAX_DTO);
    REJECTS(r.cfg.clock = NULL, P2D_XCP_ERR_CLOCK);
    REJECTS(r.cfg.timestamp_unit = 10, P2D_XCP_ERR_TIMESTAMP_UNIT);
    REJECTS(r.cfg.timestamp_ticks = 0, P2D_XCP_ERR_TIMESTAMP_TICKS);
    REJECTS(r.cfg.unlock = NULL, P2D_XCP_ERR_LOCK);
    REJECTS(r.cfg.protected_resources = 0x02, P2D_XCP_ERR_PROTECTION);
    REJECTS((r.cfg.protected_resources = 0x01, r.cfg.key = NULL), P2D_XCP_ERR_KEY);
    REJECTS((r.cfg.protected_resources = 0x01, r.cfg.seed_bytes = 0), P2D_XCP_ERR_SEED_BYTES);
    REJECTS((r.cfg.protected_resources = 0x04, r.cfg.seed_bytes = 7), P2D_XCP_ERR_SEED_BYTES); /* max_cto - 2 */
    REJECTS(r.cfg.id = NULL, P2D_XCP_ERR_ID);
    REJECTS(r.cfg.id = long_text, P2D_XCP_ERR_ID);
    REJECTS(r.cfg.a2l_name = long_text, P2D_XCP_ERR_ID);

    /* no events: no DAQ buffers needed; no calibration segment: no shadow or commit needed */
    rig_config(&r);
    r.cfg.event_count = 0;
    r.cfg.daq_memory = NULL;
    r.cfg.queue = NULL;
    r.cfg.segment_count = 1;
    r.cfg.shadow = NULL;
    r.cfg.commit = NULL;
    CHECK(p2d_xcp_init(&r.x, &r.cfg) == P2D_XCP_OK);

    for (int s = 0; s < P2D_XCP_STATUS_COUNT; ++s) {
        CHECK((s == 0) == (p2d_xcp_status_param((p2d_xcp_status_t)s)[0] == '\0'));
        CHECK((s == 0) == (p2d_xcp_status_range((p2d_xcp_status_t)s)[0] == '\0'));
    }
    CHECK(strcmp(p2d_xcp_status_param(P2D_XCP_ERR_MAX_CTO), "max_cto") == 0);
    CHECK(strcmp(p2d_xcp_status_param(P2D_XCP_STATUS_COUNT), "?") == 0);
}

static void test_connect(void)
{
    rig_t r;
    rig_init(&r);
    /* not connected: silent but for CONNECT */
    CMD(&r, 0xFD);
    CHECK(r.out_len == 0);
    CMD(&r, 0xFF, 0x02); /* mode 2 does not exist */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    /* RESOURCE CAL/PAG and DAQ; COMM_MODE_BASIC optional, slave block mode, byte granularity, Intel;
       MAX_CTO 8, MAX_DTO 16 (Intel), protocol and transport layer version 1 */
    CMD(&r, 0xFF, 0x00);
    OUT_IS(&r, RES, 0x05, 0xC0, 8, 16, 0, 1, 1);
    CMD(&r, 0xFD);
    OUT_IS(&r, RES, 0x00, 0x00, 0, 0, 0);
    CMD(&r, 0xFC);
    OUT_IS(&r, ERR, ERR_CMD_SYNCH);
    CMD(&r, 0xFB);
    OUT_IS(&r, RES, 0, 0, 0, 0, 0, 0, 0x10);
    CMD(&r, 0xF3, 0, 0, 0, 0, 0, 0, 0); /* BUILD_CHECKSUM: not supported */
    OUT_IS(&r, ERR, ERR_CMD_UNKNOWN);
    CMD(&r, 0xEB, 0x83, 0, 0); /* SET_CAL_PAGE: not supported */
    OUT_IS(&r, ERR, ERR_CMD_UNKNOWN);
    CMD(&r, 0xF6, 0, 0); /* SET_MTA too short */
    OUT_IS(&r, ERR, ERR_CMD_SYNTAX);
    CMD(&r, 0xFE);
    OUT_IS(&r, RES);
    CMD(&r, 0xFD);
    CHECK(r.out_len == 0);
    CHECK(take(&r) == 0);
    CHECK(r.depth == 0 && r.depth_max == 1 && r.locks > 0);
}

static void test_get_id(void)
{
    rig_t r;
    rig_init(&r);
    CMD(&r, 0xFF, 0x00);
    CMD(&r, 0xFA, 0x00);
    OUT_IS(&r, RES, 0, 0, 0, 13, 0, 0, 0);
    CMD(&r, 0xF5, 7);
    OUT_IS(&r, RES, 'p', 'm', 's', 'm', '2', 'd', 'o');
    CMD(&r, 0xF5, 7); /* six characters left */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xF5, 6);
    OUT_IS(&r, RES, 'f', ' ', 't', 'e', 's', 't');
    CMD(&r, 0xFA, 0x01); /* no A2L name declared */
    OUT_IS(&r, RES, 0, 0, 0, 0, 0, 0, 0);
    /* GET_DAQ_EVENT_INFO: DAQ with consistency per event, any number of lists, name length, cycle 50 x 10 us,
       priority 1; then the name by UPLOAD */
    CMD(&r, 0xD7, 0, 1, 0);
    OUT_IS(&r, RES, 0x84, 0xFF, 5, 50, 4, 1);
    CMD(&r, 0xF5, 5);
    OUT_IS(&r, RES, 's', 'p', 'e', 'e', 'd');
    CMD(&r, 0xD7, 0, 2, 0);
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
}

static void test_upload(void)
{
    rig_t r;
    rig_init(&r);
    CMD(&r, 0xFF, 0x00);
    set_mta(&r, MEAS_ADDRESS + 2u);
    OUT_IS(&r, RES);
    CMD(&r, 0xF5, 3);
    OUT_IS(&r, RES, 0x12, 0x13, 0x14);
    CMD(&r, 0xF5, 2); /* the MTA moved on */
    OUT_IS(&r, RES, 0x15, 0x16);
    /* SHORT_UPLOAD of the last byte; one byte before the segment; across its end */
    CMD(&r, 0xF4, 1, 0, 0, 0x1F, 0x10, 0, 0);
    OUT_IS(&r, RES, 0x2F);
    CMD(&r, 0xF4, 1, 0, 0, 0xFF, 0x0F, 0, 0);
    OUT_IS(&r, ERR, ERR_ACCESS_DENIED);
    CMD(&r, 0xF4, 2, 0, 0, 0x1F, 0x10, 0, 0);
    OUT_IS(&r, ERR, ERR_ACCESS_DENIED);
    CMD(&r, 0xF4, 8, 0, 0, 0x00, 0x10, 0, 0); /* more than MAX_CTO - 1 */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xF4, 1, 0, 1, 0x00, 0x10, 0, 0); /* address extension 1 */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xF6, 0, 0, 1, 0x00, 0x10, 0, 0);
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xF5, 0);
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    /* the top of the address space: the last byte, and two bytes that would wrap to address 0 */
    CMD(&r, 0xF4, 1, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF);
    OUT_IS(&r, RES, 0xAF);
    CMD(&r, 0xF4, 2, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF);
    OUT_IS(&r, ERR, ERR_ACCESS_DENIED);
    /* the calibration segment reads the values in force */
    CMD(&r, 0xF4, 4, 0, 0, 0x00, 0x20, 0, 0);
    CHECK(r.out_len == 5 && r.out[0] == RES && memcmp(r.out + 1, &r.cal.gain, 4) == 0);

    /* slave block mode: UPLOAD of 16 bytes with MAX_CTO 8: 7 + 7 + 2 data bytes, each packet led by RES */
    set_mta(&r, MEAS_ADDRESS);
    CMD(&r, 0xF5, 16);
    OUT_IS(&r, RES, 0x10, 0x11, 0x12, 0x13, 0x14, 0x15, 0x16);
    take(&r);
    OUT_IS(&r, RES, 0x17, 0x18, 0x19, 0x1A, 0x1B, 0x1C, 0x1D);
    take(&r);
    OUT_IS(&r, RES, 0x1E, 0x1F);
    CHECK(take(&r) == 0);
    CHECK(p2d_xcp_take(&r.x, r.out, 7) == 0); /* a buffer below MAX_CTO takes nothing */
}

static void test_download(void)
{
    rig_t r;
    cal_t update = {3.5f, -1.0f}, in_force;
    uint8_t packet[8] = {0xF0, 4};
    rig_init(&r);
    CMD(&r, 0xFF, 0x00);
    /* into the measurement segment, outside every segment, too long, too short a packet */
    set_mta(&r, MEAS_ADDRESS);
    CMD(&r, 0xF0, 2, 0xEE, 0xEE);
    OUT_IS(&r, ERR, ERR_WRITE_PROTECTED);
    set_mta(&r, CAL_ADDRESS + 6u); /* the last two bytes of the segment and two beyond */
    CMD(&r, 0xF0, 4, 1, 2, 3, 4);
    OUT_IS(&r, ERR, ERR_ACCESS_DENIED);
    CMD(&r, 0xF0, 7, 1, 2, 3, 4, 5, 6);
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    set_mta(&r, CAL_ADDRESS);
    CMD(&r, 0xF0, 4, 1, 2);
    OUT_IS(&r, ERR, ERR_CMD_SYNTAX);
    CHECK(r.meas[0] == 0x10 && r.cal.gain == 2.0f && r.cal.offset == -1.0f && r.commits == 0);

    /* the gain: no answer and no change until the speed sample's commit */
    CHECK(p2d_xcp_calibrate(&r.x) == P2D_XCP_COMMIT_NONE);
    memcpy(packet + 2, &update.gain, 4);
    CHECK(cmd(&r, packet, 6) == 0);
    CHECK(r.cal.gain == 2.0f);
    CMD(&r, 0xFD); /* a command while the write waits */
    OUT_IS(&r, ERR, ERR_CMD_BUSY);
    r.verdict = 0;
    CHECK(p2d_xcp_calibrate(&r.x) == P2D_XCP_COMMIT_APPLIED);
    CHECK(r.commits == 1 && r.segment == 1 && r.page.gain == 3.5f && r.page.offset == -1.0f);
    CHECK(r.cal.gain == 3.5f && r.cal.offset == -1.0f && r.x.commits_applied == 1);
    take(&r);
    OUT_IS(&r, RES);
    CHECK(p2d_xcp_calibrate(&r.x) == P2D_XCP_COMMIT_NONE);
    /* the MTA moved on to the offset: a rejected offset leaves everything as it was */
    memcpy(&in_force, &r.cal, sizeof in_force);
    update.offset = 1e9f;
    memcpy(packet + 2, &update.offset, 4);
    CHECK(cmd(&r, packet, 6) == 0);
    r.verdict = 17;
    CHECK(p2d_xcp_calibrate(&r.x) == P2D_XCP_COMMIT_REJECTED);
    CHECK(r.commits == 2 && r.page.gain == 3.5f && r.page.offset == 1e9f);
    CHECK(memcmp(&in_force, &r.cal, sizeof in_force) == 0);
    CHECK(r.x.commit_status == 17 && r.x.commits_rejected == 1);
    take(&r);
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xF4, 4, 0, 0, 0x04, 0x20, 0, 0);
    CHECK(r.out_len == 5 && memcmp(r.out + 1, &in_force.offset, 4) == 0);

    /* a master that gives up waiting (CONNECT) drops the write */
    set_mta(&r, CAL_ADDRESS);
    CHECK(cmd(&r, packet, 6) == 0);
    CMD(&r, 0xFF, 0x00);
    CHECK(r.out_len == 8 && r.out[0] == RES);
    CHECK(p2d_xcp_calibrate(&r.x) == P2D_XCP_COMMIT_NONE && r.commits == 2);
    CHECK(memcmp(&in_force, &r.cal, sizeof in_force) == 0);
}

static void test_seed_and_key(void)
{
    rig_t r;
    uint8_t seed[6], key[12], unlock[8] = {0xF7};
    rig_config(&r);
    r.cfg.protected_resources = P2D_XCP_RESOURCE_CALPAG | P2D_XCP_RESOURCE_DAQ;
    CHECK(p2d_xcp_init(&r.x, &r.cfg) == P2D_XCP_OK);
    CMD(&r, 0xFF, 0x00);
    CMD(&r, 0xFD);
    OUT_IS(&r, RES, 0x00, 0x05, 0, 0, 0);
    set_mta(&r, CAL_ADDRESS);
    CMD(&r, 0xF0, 1, 0);
    OUT_IS(&r, ERR, ERR_ACCESS_LOCKED);
    CMD(&r, 0xDA);
    OUT_IS(&r, ERR, ERR_ACCESS_LOCKED);
    CMD(&r, 0xF4, 1, 0, 0, 0x00, 0x10, 0, 0); /* UPLOAD is not protected */
    OUT_IS(&r, RES, 0x10);
    CMD(&r, 0xF7, 12, 1, 2, 3, 4, 5, 6); /* UNLOCK without a seed */
    OUT_IS(&r, ERR, ERR_SEQUENCE);
    CMD(&r, 0xF8, 0, 0x03); /* two resources at once */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xF8, 0, 0x10); /* PGM: not protected, no seed */
    OUT_IS(&r, RES, 0);

    /* the calibration resource: a 6-byte seed, a 12-byte key in two UNLOCKs */
    CMD(&r, 0xF8, 0, 0x01);
    CHECK(r.out_len == 8 && r.out[0] == RES && r.out[1] == 6);
    memcpy(seed, r.out + 2, 6);
    for (int i = 0; i < 6; ++i) {
        key[i] = (uint8_t)(seed[i] ^ 0x5Au);
        key[6 + i] = (uint8_t)~seed[i];
    }
    unlock[1] = 12;
    memcpy(unlock + 2, key, 6);
    cmd(&r, unlock, 8);
    OUT_IS(&r, RES, 0x05); /* still locked after the first part */
    unlock[1] = 6;
    memcpy(unlock + 2, key + 6, 6);
    cmd(&r, unlock, 8);
    OUT_IS(&r, RES, 0x04);
    CMD(&r, 0xF8, 0, 0x01);
    OUT_IS(&r, RES, 0);
    set_mta(&r, CAL_ADDRESS);
    CMD(&r, 0xF0, 1, 0);
    CHECK(r.out_len == 0); /* accepted: waits for the commit */
    p2d_xcp_calibrate(&r.x);
    take(&r);
    OUT_IS(&r, RES);

    /* the DAQ resource, a wrong key: refused, and the session ends */
    CMD(&r, 0xF8, 0, 0x04);
    CHECK(r.out_len == 8 && r.out[1] == 6);
    CHECK(memcmp(r.out + 2, seed, 6) != 0); /* a new seed */
    unlock[1] = 12;
    memset(unlock + 2, 0, 6);
    cmd(&r, unlock, 8);
    OUT_IS(&r, RES, 0x04);
    unlock[1] = 6;
    cmd(&r, unlock, 8);
    OUT_IS(&r, ERR, ERR_ACCESS_LOCKED);
    CMD(&r, 0xFD);
    CHECK(r.out_len == 0);
    /* a new session locks again */
    CMD(&r, 0xFF, 0x00);
    CMD(&r, 0xFD);
    OUT_IS(&r, RES, 0x00, 0x05, 0, 0, 0);
    /* a key announced longer than 32 bytes, and a second part of the wrong remaining length */
    CMD(&r, 0xF8, 0, 0x04);
    CMD(&r, 0xF7, 33, 1, 2, 3, 4, 5, 6);
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xF8, 0, 0x04);
    CMD(&r, 0xF7, 12, 1, 2, 3, 4, 5, 6);
    CMD(&r, 0xF7, 5, 1, 2, 3, 4, 5);
    OUT_IS(&r, ERR, ERR_SEQUENCE);
}

/* DAQ tables of the tests: list 0 on "current" with timestamps: one ODT of meas[0..3] and the gain; list 1 on
   "speed" every second event: ODT 0 meas[4..5], ODT 1 meas[8] */
static void configure_daq(rig_t *r)
{
    CMD(r, 0xD6);
    OUT_IS(r, RES);
    CMD(r, 0xD5, 0, 2, 0);
    OUT_IS(r, RES);
    CMD(r, 0xD4, 0, 0, 0, 1);
    CMD(r, 0xD4, 0, 1, 0, 2);
    OUT_IS(r, RES);
    CMD(r, 0xD3, 0, 0, 0, 0, 2);
    CMD(r, 0xD3, 0, 1, 0, 0, 1);
    CMD(r, 0xD3, 0, 1, 0, 1, 1);
    OUT_IS(r, RES);
    CMD(r, 0xE2, 0, 0, 0, 0, 0);
    OUT_IS(r, RES);
    CMD(r, 0xE1, 0xFF, 4, 0, 0x00, 0x10, 0, 0);
    OUT_IS(r, RES);
    CMD(r, 0xE1, 0xFF, 4, 0, 0x00, 0x20, 0, 0);
    OUT_IS(r, RES);
    CMD(r, 0xE1, 0xFF, 1, 0, 0x00, 0x10, 0, 0); /* past the ODT's two entries */
    OUT_IS(r, ERR, ERR_OUT_OF_RANGE);
    CMD(r, 0xE2, 0, 1, 0, 0, 0);
    CMD(r, 0xE1, 0xFF, 2, 0, 0x04, 0x10, 0, 0);
    CMD(r, 0xE2, 0, 1, 0, 1, 0);
    CMD(r, 0xE1, 0xFF, 1, 0, 0x08, 0x10, 0, 0);
    OUT_IS(r, RES);
    CMD(r, 0xE0, 0x10, 0, 0, 0, 0, 1, 0); /* timestamps, event 0, prescaler 1 */
    OUT_IS(r, RES);
    CMD(r, 0xE0, 0x00, 1, 0, 1, 0, 2, 0); /* event 1, prescaler 2 */
    OUT_IS(r, RES);
}

static void test_daq_info(void)
{
    rig_t r;
    rig_init(&r);
    CMD(&r, 0xFF, 0x00);
    /* dynamic, prescaler, timestamps; MAX_DAQ: lists that fit in 512 bytes; 2 events; MIN_DAQ 0; key byte */
    CMD(&r, 0xDA);
    CHECK(r.out_len == 8 && r.out[0] == RES && r.out[1] == 0x13 && r.out[4] == 2 && r.out[5] == 0 && r.out[6] == 0 &&
          r.out[7] == 0x30 && (r.out[2] | r.out[3] << 8) >= 512 / 32);
    /* granularity 1, largest entry MAX_DTO - 1, no STIM, 4-byte timestamps in unit 1 us (3), 1 tick */
    CMD(&r, 0xD9);
    OUT_IS(&r, RES, 1, 15, 1, 0, 0x34, 1, 0);
    r.now = 0xCAFE1234u;
    CMD(&r, 0xDC);
    OUT_IS(&r, RES, 0, 0, 0, 0x34, 0x12, 0xFE, 0xCA);
}

static void test_daq_sequence(void)
{
    rig_t r;
    rig_init(&r);
    CMD(&r, 0xFF, 0x00);
    CMD(&r, 0xD4, 0, 0, 0, 1); /* ALLOC_ODT before ALLOC_DAQ */
    OUT_IS(&r, ERR, ERR_SEQUENCE);
    CMD(&r, 0xD5, 0, 2, 0);
    CMD(&r, 0xD5, 0, 2, 0);
    OUT_IS(&r, ERR, ERR_SEQUENCE);
    CMD(&r, 0xD3, 0, 0, 0, 0, 1); /* ALLOC_ODT_ENTRY before ALLOC_ODT */
    OUT_IS(&r, ERR, ERR_SEQUENCE);
    CMD(&r, 0xD4, 0, 2, 0, 1); /* list 2 of 2 */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xD4, 0, 0, 0, 0);
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xD4, 0, 0, 0, 253); /* more ODTs than identifiers */
    OUT_IS(&r, ERR, ERR_MEMORY_OVERFLOW);
    CMD(&r, 0xD4, 0, 0, 0, 100); /* more than 512 bytes */
    OUT_IS(&r, ERR, ERR_MEMORY_OVERFLOW);
    CMD(&r, 0xD4, 0, 0, 0, 1);
    OUT_IS(&r, RES);
    CMD(&r, 0xD4, 0, 0, 0, 1); /* the list has its ODTs */
    OUT_IS(&r, ERR, ERR_SEQUENCE);
    CMD(&r, 0xD3, 0, 0, 0, 1, 1); /* ODT 1 of 1 */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xD3, 0, 0, 0, 0, 2);
    OUT_IS(&r, RES);
    CMD(&r, 0xD4, 0, 1, 0, 1); /* ALLOC_ODT after ALLOC_ODT_ENTRY */
    OUT_IS(&r, ERR, ERR_SEQUENCE);
    CMD(&r, 0xE1, 0xFF, 1, 0, 0x00, 0x10, 0, 0); /* WRITE_DAQ before SET_DAQ_PTR */
    OUT_IS(&r, ERR, ERR_SEQUENCE);
    CMD(&r, 0xE2, 0, 0, 0, 0, 2); /* entry 2 of 2 */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xE2, 0, 0, 0, 0, 0);
    CMD(&r, 0xE1, 0xFF, 2, 0, 0xFF, 0x0F, 0, 0); /* one byte before the segment */
    OUT_IS(&r, ERR, ERR_ACCESS_DENIED);
    CMD(&r, 0xE1, 0x03, 1, 0, 0x00, 0x10, 0, 0); /* a bit offset */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xE1, 0xFF, 16, 0, 0x00, 0x10, 0, 0); /* more than MAX_DTO - 1 */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xE1, 0xFF, 10, 0, 0x00, 0x10, 0, 0);
    OUT_IS(&r, RES);
    CMD(&r, 0xE1, 0xFF, 6, 0, 0x00, 0x10, 0, 0); /* 10 + 6 bytes: a DTO of 17 */
    OUT_IS(&r, ERR, ERR_DAQ_CONFIG);
    CMD(&r, 0xE1, 0xFF, 5, 0, 0x00, 0x10, 0, 0);
    OUT_IS(&r, RES);
    CMD(&r, 0xDE, 1, 0, 0); /* no event yet */
    OUT_IS(&r, ERR, ERR_DAQ_CONFIG);
    CMD(&r, 0xE0, 0x02, 0, 0, 0, 0, 1, 0); /* STIM */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xE0, 0x20, 0, 0, 0, 0, 1, 0); /* PID_OFF */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xE0, 0x00, 0, 0, 2, 0, 1, 0); /* event 2 of 2 */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xE0, 0x00, 0, 0, 0, 0, 0, 0); /* prescaler 0 */
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xE0, 0x10, 0, 0, 0, 0, 1, 0); /* with the timestamp, 1 + 4 + 15 bytes: too long */
    CMD(&r, 0xDE, 1, 0, 0);
    OUT_IS(&r, ERR, ERR_DAQ_CONFIG);
    CMD(&r, 0xE0, 0x00, 0, 0, 0, 0, 1, 0);
    CMD(&r, 0xDE, 1, 0, 0);
    OUT_IS(&r, RES, 0);
    CMD(&r, 0xE0, 0x00, 0, 0, 0, 0, 1, 0);
    OUT_IS(&r, ERR, ERR_DAQ_ACTIVE);
    CMD(&r, 0xE2, 0, 0, 0, 0, 0);
    OUT_IS(&r, ERR, ERR_DAQ_ACTIVE);
    CMD(&r, 0xDE, 3, 0, 0);
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    CMD(&r, 0xDD, 3);
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
    /* FREE_DAQ stops and forgets everything */
    CMD(&r, 0xD6);
    CMD(&r, 0xFD);
    OUT_IS(&r, RES, 0x00, 0x00, 0, 0, 0);
    CMD(&r, 0xDE, 1, 0, 0);
    OUT_IS(&r, ERR, ERR_OUT_OF_RANGE);
}

static void test_daq_sampling(void)
{
    rig_t r;
    rig_init(&r);
    CMD(&r, 0xFF, 0x00);
    configure_daq(&r);
    CMD(&r, 0xDE, 1, 0, 0); /* start list 0: first PID 0 */
    OUT_IS(&r, RES, 0);
    CMD(&r, 0xDE, 2, 1, 0); /* select list 1: first PID 1 (after list 0's one ODT) */
    OUT_IS(&r, RES, 1);
    CMD(&r, 0xFD);
    OUT_IS(&r, RES, 0x40, 0x00, 0, 0, 0);
    p2d_xcp_event(&r.x, 1); /* list 1 is selected, not running */
    CHECK(take(&r) == 0);
    CMD(&r, 0xDD, 1);
    OUT_IS(&r, RES);

    r.now = 0x01020304u;
    r.meas[0] = 0x77;
    p2d_xcp_event(&r.x, 0);
    CHECK(take(&r) == 13 && r.out[0] == 0 && r.out[1] == 0x04 && r.out[2] == 0x03 && r.out[3] == 0x02 &&
          r.out[4] == 0x01 && r.out[5] == 0x77 && r.out[6] == 0x11 && r.out[7] == 0x12 && r.out[8] == 0x13 &&
          memcmp(r.out + 9, &r.cal.gain, 4) == 0);
    CHECK(take(&r) == 0);
    p2d_xcp_event(&r.x, 1); /* the first event after the start samples */
    take(&r);
    OUT_IS(&r, 1, 0x14, 0x15);
    take(&r);
    OUT_IS(&r, 2, 0x18);
    r.meas[4] = 0x99;
    p2d_xcp_event(&r.x, 1); /* prescaler 2: skipped */
    CHECK(take(&r) == 0);
    p2d_xcp_event(&r.x, 1);
    take(&r);
    OUT_IS(&r, 1, 0x99, 0x15);
    take(&r);
    OUT_IS(&r, 2, 0x18);
    CHECK(r.x.dtos_sent == 5 && r.x.dtos_lost == 0);
    /* a sample of list 0 takes 2 + 13 bytes of the 128-byte queue: the ninth without taking finds no room */
    for (int i = 0; i < 9; ++i) p2d_xcp_event(&r.x, 0);
    CHECK(r.x.dtos_lost == 1);
    for (int i = 0; i < 8; ++i) CHECK(take(&r) == 13 && r.out[0] == 0);
    CHECK(take(&r) == 0);
    /* stop list 1 alone, then all; DISCONNECT stops too */
    CMD(&r, 0xDE, 0, 1, 0);
    OUT_IS(&r, RES, 1);
    p2d_xcp_event(&r.x, 1);
    p2d_xcp_event(&r.x, 1);
    CHECK(take(&r) == 0);
    CMD(&r, 0xDE, 2, 0, 0);
    CMD(&r, 0xDD, 2); /* stop the selected list 0 */
    OUT_IS(&r, RES);
    p2d_xcp_event(&r.x, 0);
    CHECK(take(&r) == 0);
    CMD(&r, 0xDE, 1, 0, 0);
    CMD(&r, 0xFE);
    p2d_xcp_event(&r.x, 0);
    CHECK(take(&r) == 0);
    CHECK(r.depth == 0 && r.depth_max == 1);
}

/* an ODT entry allocated but never written adds nothing to the DTO */
static void test_daq_unwritten_entry(void)
{
    rig_t r;
    rig_init(&r);
    CMD(&r, 0xFF, 0x00);
    CMD(&r, 0xD5, 0, 1, 0);
    CMD(&r, 0xD4, 0, 0, 0, 1);
    CMD(&r, 0xD3, 0, 0, 0, 0, 3);
    CMD(&r, 0xE2, 0, 0, 0, 0, 1); /* the middle entry only */
    CMD(&r, 0xE1, 0xFF, 2, 0, 0x02, 0x10, 0, 0);
    CMD(&r, 0xE0, 0x00, 0, 0, 1, 0, 1, 0);
    CMD(&r, 0xDE, 1, 0, 0);
    OUT_IS(&r, RES, 0);
    p2d_xcp_event(&r.x, 1);
    take(&r);
    OUT_IS(&r, 0, 0x12, 0x13);
}

static void test_link_watchdog(void)
{
    rig_t r;
    rig_init(&r);
    r.now = 0xFFFFFFF0u; /* across the clock's wrap */
    CHECK(!p2d_xcp_link_check(&r.x));
    CMD(&r, 0xFF, 0x00);
    r.now += 100u;
    CHECK(!p2d_xcp_link_check(&r.x));
    r.now += 1u;
    CHECK(p2d_xcp_link_check(&r.x));
    r.now += 0x80000000u; /* latched, whatever the clock says */
    CHECK(p2d_xcp_link_check(&r.x));
    CMD(&r, 0xFD); /* the master is back */
    CHECK(!p2d_xcp_link_check(&r.x));
    CMD(&r, 0xFE); /* a clean disconnect: no watchdog */
    r.now += 1000u;
    CHECK(!p2d_xcp_link_check(&r.x));
    rig_config(&r);
    r.cfg.link_timeout_ticks = 0;
    CHECK(p2d_xcp_init(&r.x, &r.cfg) == P2D_XCP_OK);
    CMD(&r, 0xFF, 0x00);
    r.now += 1000000u;
    CHECK(!p2d_xcp_link_check(&r.x));
}

static void test_framing(void)
{
    p2d_xcp_frame_t tx, rx;
    uint8_t frame[16] = {0, 0, 0, 0, 0xFF, 0x00};
    size_t n, got = 0;
    p2d_xcp_frame_init(&tx, false);
    /* LEN 2, CTR 0, then CTR 1 */
    CHECK(p2d_xcp_frame_tx(&tx, frame, 2) == 6 && frame[0] == 2 && frame[1] == 0 && frame[2] == 0 && frame[3] == 0);
    CHECK(p2d_xcp_frame_tx(&tx, frame, 2) == 6 && frame[2] == 1 && frame[3] == 0);
    tx.tx_counter = 0xFFFF;
    CHECK(p2d_xcp_frame_tx(&tx, frame, 2) == 6 && frame[2] == 0xFF && frame[3] == 0xFF && tx.tx_counter == 0);
    /* with a checksum: (2 + 0 + 0 + 0 + 0xFF + 0x00) mod 256 */
    p2d_xcp_frame_init(&tx, true);
    n = p2d_xcp_frame_tx(&tx, frame, 2);
    CHECK(n == 7 && frame[6] == 0x01);

    /* receiving it byte by byte: complete at the last byte */
    p2d_xcp_frame_init(&rx, true);
    for (size_t i = 0; i < n; ++i) {
        got = p2d_xcp_frame_rx(&rx, frame[i]);
        CHECK((got != 0) == (i == n - 1));
    }
    CHECK(got == 2 && rx.packet[0] == 0xFF && rx.packet[1] == 0x00 && rx.rx_errors == 0);
    /* a wrong checksum drops the frame; the next one arrives */
    frame[6] = 0x02;
    for (size_t i = 0; i < n; ++i) got = p2d_xcp_frame_rx(&rx, frame[i]);
    CHECK(got == 0 && rx.rx_errors == 1);
    frame[6] = 0x01;
    for (size_t i = 0; i < n; ++i) got = p2d_xcp_frame_rx(&rx, frame[i]);
    CHECK(got == 2);
    /* LEN 0 and LEN 256: dropped at the header */
    p2d_xcp_frame_init(&rx, false);
    for (int i = 0; i < 4; ++i) CHECK(p2d_xcp_frame_rx(&rx, 0) == 0);
    CHECK(rx.rx_errors == 1);
    CHECK(p2d_xcp_frame_rx(&rx, 0x00) == 0 && p2d_xcp_frame_rx(&rx, 0x01) == 0);
    CHECK(p2d_xcp_frame_rx(&rx, 0x00) == 0 && p2d_xcp_frame_rx(&rx, 0x00) == 0 && rx.rx_errors == 2);
    /* a partial frame forgotten at a gap */
    CHECK(p2d_xcp_frame_rx(&rx, 0x01) == 0 && p2d_xcp_frame_rx(&rx, 0x00) == 0);
    p2d_xcp_frame_rx_reset(&rx);
    {
        const uint8_t two[] = {1, 0, 7, 0, 0xFD, 1, 0, 0, 0, 0xFC};
        size_t done[10];
        for (int i = 0; i < 10; ++i) done[i] = p2d_xcp_frame_rx(&rx, two[i]);
        CHECK(done[4] == 1 && done[9] == 1 && rx.packet[0] == 0xFC && done[3] == 0 && done[8] == 0);
    }
    CHECK(p2d_xcp_frame_tx(&tx, frame, 0) == 0);
}

static void test_can(void)
{
    uint8_t frame[64];
    CHECK(p2d_xcp_can_length(3, 0) == 3 && p2d_xcp_can_length(3, 8) == 8 && p2d_xcp_can_length(8, 0) == 8);
    CHECK(p2d_xcp_can_length(9, 0) == 12 && p2d_xcp_can_length(13, 0) == 16 && p2d_xcp_can_length(21, 0) == 24);
    CHECK(p2d_xcp_can_length(25, 0) == 32 && p2d_xcp_can_length(33, 0) == 48 && p2d_xcp_can_length(49, 0) == 64);
    CHECK(p2d_xcp_can_length(3, 64) == 64 && p2d_xcp_can_length(65, 0) == 0 && p2d_xcp_can_length(0, 8) == 0);
    CHECK(p2d_xcp_can_length(3, 65) == 0);
    memset(frame, 0xFF, sizeof frame);
    frame[0] = 0xFF;
    frame[1] = 0x00;
    CHECK(p2d_xcp_can_pad(frame, 2, 8, 0x55) == 8 && frame[1] == 0x00 && frame[2] == 0x55 && frame[7] == 0x55 &&
          frame[8] == 0xFF);
    CHECK(p2d_xcp_can_dlc(0) == 0 && p2d_xcp_can_dlc(8) == 8 && p2d_xcp_can_dlc(12) == 9 && p2d_xcp_can_dlc(48) == 14 &&
          p2d_xcp_can_dlc(64) == 15 && p2d_xcp_can_dlc(10) == 0xFF);
}

static void test_guard(void)
{
    p2d_xcp_guard_t g;
    p2d_xcp_guard_config_t cfg = {1e-3f, 1000.0f, 2e-3f};
    bool on = false;
    const float ramp[6] = {4.5f, 3.5f, 2.5f, 1.5f, 0.5f, 0.0f};
    p2d_xcp_guard_config_t bad = cfg;
    CHECK(p2d_xcp_guard_init(NULL, &cfg) == P2D_XCP_ERR_NULL);
    bad.Ts_s = 0.0f;
    CHECK(p2d_xcp_guard_init(&g, &bad) == P2D_XCP_ERR_GUARD_TS);
    bad = cfg;
    bad.ramp_radps_per_s = INFINITY;
    CHECK(p2d_xcp_guard_init(&g, &bad) == P2D_XCP_ERR_GUARD_RAMP);
    bad.ramp_radps_per_s = 1e-44f; /* times Ts: 0 in float32 */
    CHECK(p2d_xcp_guard_init(&g, &bad) == P2D_XCP_ERR_GUARD_RAMP);
    bad = cfg;
    bad.hold_s = -1.0f;
    CHECK(p2d_xcp_guard_init(&g, &bad) == P2D_XCP_ERR_GUARD_HOLD);
    bad.hold_s = 1e5f; /* 1e8 samples */
    CHECK(p2d_xcp_guard_init(&g, &bad) == P2D_XCP_ERR_GUARD_HOLD);

    /* 1000 rad/s^2 at 1 ms: 1 rad/s per sample; 2 ms of hold: 2 samples */
    CHECK(p2d_xcp_guard_init(&g, &cfg) == P2D_XCP_OK && g.hold_samples == 2);
    CHECK(p2d_xcp_guard_step(&g, false, 5.5f, &on) == 5.5f && on);
    for (int k = 0; k < 6; ++k) {
        CHECK_CLOSE(p2d_xcp_guard_step(&g, true, 100.0f, &on), ramp[k], 1e-6);
        CHECK(on);
    }
    CHECK(g.state == P2D_XCP_GUARD_HOLDING);
    for (int k = 0; k < 2; ++k) CHECK(p2d_xcp_guard_step(&g, false, 100.0f, &on) == 0.0f && on);
    CHECK(p2d_xcp_guard_step(&g, false, 100.0f, &on) == 0.0f && !on && g.state == P2D_XCP_GUARD_STOPPED);
    for (int k = 0; k < 3; ++k) CHECK(p2d_xcp_guard_step(&g, false, 100.0f, &on) == 0.0f && !on); /* latched */
    p2d_xcp_guard_reset(&g);
    CHECK(p2d_xcp_guard_step(&g, false, -2.25f, &on) == -2.25f && on);
    CHECK(p2d_xcp_guard_step(&g, true, -2.25f, &on) == -1.25f && on);
    CHECK(p2d_xcp_guard_step(&g, true, -2.25f, &on) == -0.25f && on);
    CHECK(p2d_xcp_guard_step(&g, true, -2.25f, &on) == 0.0f && on);
    /* a reference that is not finite drops to zero at once */
    p2d_xcp_guard_reset(&g);
    (void)p2d_xcp_guard_step(&g, false, NAN, &on);
    CHECK(p2d_xcp_guard_step(&g, true, NAN, &on) == 0.0f && g.state == P2D_XCP_GUARD_HOLDING);
}

int main(void)
{
    test_init_validation();
    test_connect();
    test_get_id();
    test_upload();
    test_download();
    test_seed_and_key();
    test_daq_info();
    test_daq_sequence();
    test_daq_sampling();
    test_daq_unwritten_entry();
    test_link_watchdog();
    test_framing();
    test_can();
    test_guard();
    return check_summary();
}
