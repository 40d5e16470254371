/*
 * pmsm2dof: the XCP slave (xcp.h). Packet layouts: ASAM MCD-1 XCP 1.x protocol
 * layer (commands, responses, DTOs with an absolute ODT number), XCP on
 * Ethernet / SxI (LEN and CTR header), XCP on CAN (one packet per frame).
 */
#include "pmsm2dof/xcp.h"

#include <math.h>

/* Packet identifiers of the slave's packets. */
enum { PID_RES = 0xFF, PID_ERR = 0xFE };

/* Commands. */
enum {
    CMD_CONNECT = 0xFF,
    CMD_DISCONNECT = 0xFE,
    CMD_GET_STATUS = 0xFD,
    CMD_SYNCH = 0xFC,
    CMD_GET_COMM_MODE_INFO = 0xFB,
    CMD_GET_ID = 0xFA,
    CMD_GET_SEED = 0xF8,
    CMD_UNLOCK = 0xF7,
    CMD_SET_MTA = 0xF6,
    CMD_UPLOAD = 0xF5,
    CMD_SHORT_UPLOAD = 0xF4,
    CMD_DOWNLOAD = 0xF0,
    CMD_SET_DAQ_PTR = 0xE2,
    CMD_WRITE_DAQ = 0xE1,
    CMD_SET_DAQ_LIST_MODE = 0xE0,
    CMD_START_STOP_DAQ_LIST = 0xDE,
    CMD_START_STOP_SYNCH = 0xDD,
    CMD_GET_DAQ_CLOCK = 0xDC,
    CMD_GET_DAQ_PROCESSOR_INFO = 0xDA,
    CMD_GET_DAQ_RESOLUTION_INFO = 0xD9,
    CMD_GET_DAQ_EVENT_INFO = 0xD7,
    CMD_FREE_DAQ = 0xD6,
    CMD_ALLOC_DAQ = 0xD5,
    CMD_ALLOC_ODT = 0xD4,
    CMD_ALLOC_ODT_ENTRY = 0xD3
};

/* Error codes. */
enum {
    ERR_CMD_SYNCH = 0x00,
    ERR_CMD_BUSY = 0x10,
    ERR_DAQ_ACTIVE = 0x11,
    ERR_CMD_UNKNOWN = 0x20,
    ERR_CMD_SYNTAX = 0x21,
    ERR_OUT_OF_RANGE = 0x22,
    ERR_WRITE_PROTECTED = 0x23,
    ERR_ACCESS_DENIED = 0x24,
    ERR_ACCESS_LOCKED = 0x25,
    ERR_SEQUENCE = 0x29,
    ERR_DAQ_CONFIG = 0x2A,
    ERR_MEMORY_OVERFLOW = 0x30
};

/* Every resource GET_SEED names: CAL/PAG, DAQ, STIM, PGM. */
#define RESOURCES_ALL 0x1Du
/* DTO identifiers 0..0xFB: the absolute ODT numbers. */
#define ODT_COUNT_MAX 0xFCu
/* Bytes of a DTO's timestamp. */
#define TIMESTAMP_BYTES 4u
/* Longest identification text and event name [bytes]. */
#define TEXT_MAX_BYTES 255u
/* Bytes in front of each DTO in the queue: its length. */
#define QUEUE_LENGTH_BYTES 2u

/* flags of a DAQ list */
enum { LIST_MODE_SET = 1, LIST_TIMESTAMP = 2, LIST_RUNNING = 4, LIST_SELECTED = 8 };

/* An ODT entry: bytes sampled from a segment. */
typedef struct {
    const uint8_t *source; /* first byte, inside a segment */
    uint32_t size_bytes;   /* 0: not written */
} xcp_entry_t;

/* An object descriptor table: the entries of one DTO. */
typedef struct {
    xcp_entry_t *entries;
    uint32_t entry_count;   /* entries allocated */
    uint32_t payload_bytes; /* sum of the entries' sizes [bytes] */
} xcp_odt_t;

typedef struct {
    xcp_odt_t *odts;
    uint32_t odt_count;    /* ODTs allocated */
    uint32_t sample_bytes; /* queue bytes of one sample, set when started [bytes] */
    uint16_t event;        /* event number (SET_DAQ_LIST_MODE) */
    uint8_t first_pid;     /* identifier of its first ODT, set when started or selected */
    uint8_t prescaler;     /* sample at every prescaler-th event, >= 1 */
    uint8_t prescale_count;
    uint8_t flags; /* LIST_* */
} xcp_list_t;

/* Alignment of the tables in daq_memory. */
typedef union {
    void *pointer;
    uint32_t word;
} xcp_align_t;

static void lock(const p2d_xcp_t *x)
{
    if (x->config.lock != 0) x->config.lock(x->config.user);
}

static void unlock(const p2d_xcp_t *x)
{
    if (x->config.unlock != 0) x->config.unlock(x->config.user);
}

/* n bytes from src to dst, not overlapping. The library calls nothing outside <math.h>; the compiler would turn
   a plain loop into a call of memcpy, hence the volatile destination. */
static void copy_bytes(uint8_t *dst, const uint8_t *src, uint32_t n)
{
    volatile uint8_t *d = dst;
    for (uint32_t i = 0; i < n; ++i) d[i] = src[i];
}

/* n bytes of value at dst (as copy_bytes, not memset) */
static void fill_bytes(uint8_t *dst, uint8_t value, uint32_t n)
{
    volatile uint8_t *d = dst;
    for (uint32_t i = 0; i < n; ++i) d[i] = value;
}

/* An n-byte number (n <= 4) in the slave's byte order, the order CONNECT reports. */
static uint32_t get(const p2d_xcp_t *x, const uint8_t *p, uint32_t n)
{
    uint32_t v = 0;
    for (uint32_t i = 0; i < n; ++i) v |= (uint32_t)p[x->byte_order ? n - 1u - i : i] << (8u * i);
    return v;
}

static void put(const p2d_xcp_t *x, uint8_t *p, uint32_t v, uint32_t n)
{
    for (uint32_t i = 0; i < n; ++i) p[x->byte_order ? n - 1u - i : i] = (uint8_t)(v >> (8u * i));
}

/* Length of a text of at most TEXT_MAX_BYTES + 1 characters (the init checks TEXT_MAX_BYTES). */
static uint32_t text_bytes(const char *s)
{
    uint32_t n = 0;
    while (n <= TEXT_MAX_BYTES && s[n] != '\0') n++;
    return n;
}

/* ---------------------------------------------------------------- init */

typedef struct {
    const char *param; /* configuration field */
    const char *range; /* valid range */
} xcp_status_text_t;

static const xcp_status_text_t XCP_STATUS_TEXT[P2D_XCP_STATUS_COUNT] = {
    [P2D_XCP_OK] = {"", ""},
    [P2D_XCP_ERR_NULL] = {"pointer", "non-NULL"},
    [P2D_XCP_ERR_SEGMENTS] = {"segments", "non-NULL, segment_count from 1 to 65535"},
    [P2D_XCP_ERR_SEGMENT_MEMORY] = {"segments[i].memory", "non-NULL"},
    [P2D_XCP_ERR_SEGMENT_SIZE] = {"segments[i].size_bytes", ">= 1, with address + size_bytes <= 2^32"},
    [P2D_XCP_ERR_SEGMENT_ACCESS] = {"segments[i].access", "measurement (0) or calibration (1)"},
    [P2D_XCP_ERR_SEGMENT_OVERLAP] = {"segments[i].address", "no two segments share an XCP address"},
    [P2D_XCP_ERR_SHADOW] = {"shadow_bytes", "non-NULL shadow of at least the largest calibration segment's size"},
    [P2D_XCP_ERR_COMMIT] = {"commit", "non-NULL when a segment is a calibration segment"},
    [P2D_XCP_ERR_EVENTS] = {"events", "non-NULL when event_count > 0"},
    [P2D_XCP_ERR_EVENT_NAME] = {"events[i].name", "non-NULL, 1 to 255 characters"},
    [P2D_XCP_ERR_EVENT_CYCLE_UNIT] = {"events[i].cycle_unit", "an XCP time unit from 0 (1 ns) to 9 (1 s)"},
    [P2D_XCP_ERR_DAQ_MEMORY] = {"daq_memory", "non-NULL with daq_memory_bytes > 0 when event_count > 0"},
    [P2D_XCP_ERR_QUEUE] = {"queue_bytes", "non-NULL queue of at least max_dto + 2 bytes when event_count > 0"},
    [P2D_XCP_ERR_MAX_CTO] = {"max_cto", "from 8 to 255"},
    [P2D_XCP_ERR_MAX_DTO] = {"max_dto", "from 8 to 65531"},
    [P2D_XCP_ERR_CLOCK] = {"clock", "non-NULL"},
    [P2D_XCP_ERR_TIMESTAMP_UNIT] = {"timestamp_unit", "an XCP time unit from 0 (1 ns) to 9 (1 s)"},
    [P2D_XCP_ERR_TIMESTAMP_TICKS] = {"timestamp_ticks", ">= 1"},
    [P2D_XCP_ERR_LOCK] = {"lock", "lock and unlock both NULL or both non-NULL"},
    [P2D_XCP_ERR_PROTECTION] = {"protected_resources", "a combination of calibration (0x01) and DAQ (0x04)"},
    [P2D_XCP_ERR_KEY] = {"key", "non-NULL when protected_resources is not 0"},
    [P2D_XCP_ERR_SEED_BYTES] = {"seed_bytes", "from 1 to min(32, max_cto - 2) when protected_resources is not 0"},
    [P2D_XCP_ERR_ID] = {"id", "non-NULL, at most 255 characters (a2l_name: NULL or at most 255 characters)"},
    [P2D_XCP_ERR_GUARD_TS] = {"Ts_s", "finite and > 0"},
    [P2D_XCP_ERR_GUARD_RAMP] = {"ramp_radps_per_s", "finite and > 0, with ramp_radps_per_s*Ts_s > 0 in float32"},
    [P2D_XCP_ERR_GUARD_HOLD] = {"hold_s", "finite, >= 0 and <= 2^24 Ts_s"},
};

const char *p2d_xcp_status_param(p2d_xcp_status_t status)
{
    if ((unsigned)status >= (unsigned)P2D_XCP_STATUS_COUNT) return "?";
    return XCP_STATUS_TEXT[status].param;
}

const char *p2d_xcp_status_range(p2d_xcp_status_t status)
{
    if ((unsigned)status >= (unsigned)P2D_XCP_STATUS_COUNT) return "?";
    return XCP_STATUS_TEXT[status].range;
}

static p2d_xcp_status_t check_segments(const p2d_xcp_config_t *c)
{
    uint32_t largest_calibration = 0;
    if (c->segments == 0 || c->segment_count == 0u) return P2D_XCP_ERR_SEGMENTS;
    for (uint32_t i = 0; i < c->segment_count; ++i) {
        const p2d_xcp_segment_t *s = &c->segments[i];
        if (s->memory == 0) return P2D_XCP_ERR_SEGMENT_MEMORY;
        if (s->size_bytes == 0u || s->size_bytes - 1u > UINT32_MAX - s->address) return P2D_XCP_ERR_SEGMENT_SIZE;
        if (s->access != P2D_XCP_MEASUREMENT && s->access != P2D_XCP_CALIBRATION) return P2D_XCP_ERR_SEGMENT_ACCESS;
        for (uint32_t j = 0; j < i; ++j) {
            const p2d_xcp_segment_t *t = &c->segments[j];
            /* [a, a + n) and [b, b + m) meet when a - b < m (unsigned) or b - a < n */
            if (s->address - t->address < t->size_bytes || t->address - s->address < s->size_bytes) {
                return P2D_XCP_ERR_SEGMENT_OVERLAP;
            }
        }
        if (s->access == P2D_XCP_CALIBRATION && s->size_bytes > largest_calibration) {
            largest_calibration = s->size_bytes;
        }
    }
    if (largest_calibration > 0u) {
        if (c->shadow == 0 || c->shadow_bytes < largest_calibration) return P2D_XCP_ERR_SHADOW;
        if (c->commit == 0) return P2D_XCP_ERR_COMMIT;
    }
    return P2D_XCP_OK;
}

static p2d_xcp_status_t check_daq(const p2d_xcp_config_t *c)
{
    if (c->event_count == 0u) return P2D_XCP_OK;
    if (c->events == 0) return P2D_XCP_ERR_EVENTS;
    for (uint32_t i = 0; i < c->event_count; ++i) {
        const p2d_xcp_event_t *e = &c->events[i];
        if (e->name == 0 || e->name[0] == '\0' || text_bytes(e->name) > TEXT_MAX_BYTES) {
            return P2D_XCP_ERR_EVENT_NAME;
        }
        if (e->cycle_unit > 9u) return P2D_XCP_ERR_EVENT_CYCLE_UNIT;
    }
    if (c->daq_memory == 0 || c->daq_memory_bytes == 0u) return P2D_XCP_ERR_DAQ_MEMORY;
    if (c->queue == 0 || c->queue_bytes < (uint32_t)c->max_dto + QUEUE_LENGTH_BYTES) return P2D_XCP_ERR_QUEUE;
    return P2D_XCP_OK;
}

static p2d_xcp_status_t check_config(const p2d_xcp_config_t *c)
{
    p2d_xcp_status_t status = check_segments(c);
    if (status != P2D_XCP_OK) return status;
    if (c->max_cto < 8u) return P2D_XCP_ERR_MAX_CTO;
    if (c->max_dto < 8u || c->max_dto > 65531u) return P2D_XCP_ERR_MAX_DTO;
    status = check_daq(c);
    if (status != P2D_XCP_OK) return status;
    if (c->clock == 0) return P2D_XCP_ERR_CLOCK;
    if (c->timestamp_unit > 9u) return P2D_XCP_ERR_TIMESTAMP_UNIT;
    if (c->timestamp_ticks == 0u) return P2D_XCP_ERR_TIMESTAMP_TICKS;
    if ((c->lock == 0) != (c->unlock == 0)) return P2D_XCP_ERR_LOCK;
    if ((c->protected_resources & ~(unsigned)(P2D_XCP_RESOURCE_CALPAG | P2D_XCP_RESOURCE_DAQ)) != 0u) {
        return P2D_XCP_ERR_PROTECTION;
    }
    if (c->protected_resources != 0u) {
        if (c->key == 0) return P2D_XCP_ERR_KEY;
        if (c->seed_bytes == 0u || c->seed_bytes > P2D_XCP_KEY_MAX_BYTES || c->seed_bytes > c->max_cto - 2u) {
            return P2D_XCP_ERR_SEED_BYTES;
        }
    }
    if (c->id == 0 || text_bytes(c->id) > TEXT_MAX_BYTES) return P2D_XCP_ERR_ID;
    if (c->a2l_name != 0 && text_bytes(c->a2l_name) > TEXT_MAX_BYTES) return P2D_XCP_ERR_ID;
    return P2D_XCP_OK;
}

p2d_xcp_status_t p2d_xcp_init(p2d_xcp_t *x, const p2d_xcp_config_t *cfg)
{
    const union {
        uint16_t word;
        uint8_t bytes[2];
    } probe = {1};
    p2d_xcp_status_t status;
    if (x == 0 || cfg == 0) return P2D_XCP_ERR_NULL;
    status = check_config(cfg);
    if (status != P2D_XCP_OK) return status;
    fill_bytes((uint8_t *)x, 0, (uint32_t)sizeof *x);
    copy_bytes((uint8_t *)&x->config, (const uint8_t *)cfg, (uint32_t)sizeof *cfg);
    x->byte_order = (uint8_t)(probe.bytes[0] == 1u ? 0u : 1u);
    x->seed_state = 0x9E3779B9u;
    return P2D_XCP_OK;
}

/* ---------------------------------------------------------------- responses */

static void respond(p2d_xcp_t *x, uint16_t bytes)
{
    x->response[0] = PID_RES;
    x->response_bytes = bytes;
    x->response_taken = 0;
}

static void fail(p2d_xcp_t *x, uint8_t code)
{
    x->response[0] = PID_ERR;
    x->response[1] = code;
    x->response_bytes = 2;
    x->response_taken = 0;
}

/* ---------------------------------------------------------------- memory */

/* The segment that holds all of [address, address + n), n >= 1, or NULL (0). */
static const p2d_xcp_segment_t *find_segment(const p2d_xcp_t *x, uint32_t address, uint32_t n, uint16_t *index)
{
    for (uint16_t i = 0; i < x->config.segment_count; ++i) {
        const p2d_xcp_segment_t *s = &x->config.segments[i];
        if (address - s->address < s->size_bytes && n <= s->size_bytes - (address - s->address)) {
            if (index != 0) *index = i;
            return s;
        }
    }
    return 0;
}

/* The n bytes at an XCP address, read from their segment into out; false (and ERR_ACCESS_DENIED) if none holds them. */
static bool read_memory(p2d_xcp_t *x, uint32_t address, uint32_t n, uint8_t *out)
{
    const p2d_xcp_segment_t *s = find_segment(x, address, n, 0);
    if (s == 0) {
        fail(x, ERR_ACCESS_DENIED);
        return false;
    }
    copy_bytes(out, (const uint8_t *)s->memory + (address - s->address), n);
    return true;
}

/* ---------------------------------------------------------------- DAQ tables */

static xcp_list_t *lists(const p2d_xcp_t *x) { return (xcp_list_t *)x->daq_lists; }

/* bytes of daq_memory, aligned for the tables, or NULL (0) when they do not fit */
static void *daq_alloc(p2d_xcp_t *x, uint32_t count, uint32_t size)
{
    uint8_t *base = (uint8_t *)x->config.daq_memory;
    uint32_t align = (uint32_t)sizeof(xcp_align_t);
    uint32_t misalign = (uint32_t)((uintptr_t)(base + x->daq_used_bytes) % align);
    uint32_t start = x->daq_used_bytes + (misalign != 0u ? align - misalign : 0u);
    uint32_t room = start <= x->config.daq_memory_bytes ? x->config.daq_memory_bytes - start : 0u;
    void *p;
    if (count > room / size) return 0;
    p = base + start;
    fill_bytes((uint8_t *)p, 0, count * size);
    x->daq_used_bytes = start + count * size;
    return p;
}

static void update_daq_running(p2d_xcp_t *x)
{
    uint8_t running = 0;
    for (uint32_t i = 0; i < x->daq_list_count; ++i) {
        if (lists(x)[i].flags & LIST_RUNNING) running = 1;
    }
    x->daq_running = running;
}

static void stop_all(p2d_xcp_t *x)
{
    for (uint32_t i = 0; i < x->daq_list_count; ++i) {
        lists(x)[i].flags = (uint8_t)(lists(x)[i].flags & ~(LIST_RUNNING | LIST_SELECTED));
    }
    x->daq_running = 0;
}

static uint8_t first_pid(const p2d_xcp_t *x, uint32_t list)
{
    uint32_t pid = 0;
    for (uint32_t i = 0; i < list; ++i) pid += lists(x)[i].odt_count;
    return (uint8_t)pid; /* < ODT_COUNT_MAX: ALLOC_ODT keeps the total below it */
}

/* Whether a list can run: its event set, every DTO within max_dto, one sample within the queue. Sets its
   sample_bytes and first_pid. */
static bool list_ready(p2d_xcp_t *x, uint32_t index)
{
    xcp_list_t *l = &lists(x)[index];
    uint32_t sample = 0;
    if (!(l->flags & LIST_MODE_SET) || l->odt_count == 0u) return false;
    for (uint32_t j = 0; j < l->odt_count; ++j) {
        uint32_t dto =
            1u + l->odts[j].payload_bytes + ((j == 0u && (l->flags & LIST_TIMESTAMP)) ? TIMESTAMP_BYTES : 0u);
        if (dto > x->config.max_dto) return false;
        sample += QUEUE_LENGTH_BYTES + dto;
    }
    if (sample > x->config.queue_bytes) return false;
    l->sample_bytes = sample;
    l->first_pid = first_pid(x, index);
    return true;
}

/* ---------------------------------------------------------------- DTO queue */

static void queue_put(p2d_xcp_t *x, const uint8_t *bytes, uint32_t n)
{
    uint32_t first = x->config.queue_bytes - x->queue_head;
    if (first > n) first = n;
    copy_bytes(x->config.queue + x->queue_head, bytes, first);
    copy_bytes(x->config.queue, bytes + first, n - first);
    x->queue_head = (x->queue_head + n) % x->config.queue_bytes;
    x->queue_used += n;
}

static void queue_get(p2d_xcp_t *x, uint8_t *bytes, uint32_t n)
{
    uint32_t first = x->config.queue_bytes - x->queue_tail;
    if (first > n) first = n;
    copy_bytes(bytes, x->config.queue + x->queue_tail, first);
    copy_bytes(bytes + first, x->config.queue, n - first);
    x->queue_tail = (x->queue_tail + n) % x->config.queue_bytes;
    x->queue_used -= n;
}

/* One sample of a list: every ODT as a DTO (PID, timestamp in the first if enabled, the entries). */
static void sample_list(p2d_xcp_t *x, const xcp_list_t *l, uint32_t now)
{
    for (uint32_t j = 0; j < l->odt_count; ++j) {
        const xcp_odt_t *o = &l->odts[j];
        uint8_t head[QUEUE_LENGTH_BYTES + 1u + TIMESTAMP_BYTES];
        uint32_t head_bytes = QUEUE_LENGTH_BYTES + 1u, dto = 1u + o->payload_bytes;
        if (j == 0u && (l->flags & LIST_TIMESTAMP)) {
            put(x, head + head_bytes, now, 4);
            head_bytes += TIMESTAMP_BYTES;
            dto += TIMESTAMP_BYTES;
        }
        head[0] = (uint8_t)(dto & 0xFFu);
        head[1] = (uint8_t)(dto >> 8);
        head[QUEUE_LENGTH_BYTES] = (uint8_t)(l->first_pid + j);
        queue_put(x, head, head_bytes);
        for (uint32_t k = 0; k < o->entry_count; ++k) {
            if (o->entries[k].size_bytes > 0u) queue_put(x, o->entries[k].source, o->entries[k].size_bytes);
        }
    }
}

void p2d_xcp_event(p2d_xcp_t *x, uint16_t event)
{
    uint32_t now;
    if (x == 0) return;
    now = x->config.clock(x->config.user);
    lock(x);
    if (x->daq_running) {
        for (uint32_t i = 0; i < x->daq_list_count; ++i) {
            xcp_list_t *l = &lists(x)[i];
            if (!(l->flags & LIST_RUNNING) || l->event != event) continue;
            if (++l->prescale_count < l->prescaler) continue;
            l->prescale_count = 0;
            if (x->config.queue_bytes - x->queue_used < l->sample_bytes) {
                x->dtos_lost++;
                continue;
            }
            sample_list(x, l, now);
        }
    }
    unlock(x);
}

uint32_t p2d_xcp_take(p2d_xcp_t *x, uint8_t *packet, uint32_t capacity)
{
    uint32_t n = 0;
    if (x == 0 || packet == 0 || capacity < x->config.max_cto || capacity < x->config.max_dto) return 0;
    lock(x);
    if (x->response_bytes > 0u) {
        uint32_t data = (uint32_t)x->config.max_cto - 1u, left = (uint32_t)x->response_bytes - x->response_taken;
        /* the first packet as queued; an UPLOAD longer than one packet goes on in packets of PID_RES and data
           (slave block mode) */
        if (x->response_taken == 0u) {
            left--;
            x->response_taken = 1;
        }
        if (left > data) left = data;
        packet[0] = x->response[0];
        copy_bytes(packet + 1, x->response + x->response_taken, left);
        x->response_taken = (uint16_t)(x->response_taken + left);
        n = 1u + left;
        if (x->response_taken >= x->response_bytes) {
            x->response_bytes = 0;
            x->response_taken = 0;
        }
    } else if (x->queue_used > 0u) {
        uint8_t length[QUEUE_LENGTH_BYTES];
        queue_get(x, length, QUEUE_LENGTH_BYTES);
        n = (uint32_t)length[0] | (uint32_t)length[1] << 8;
        queue_get(x, packet, (uint32_t)n);
        x->dtos_sent++;
    }
    unlock(x);
    return n;
}

/* ---------------------------------------------------------------- commands */

static void cmd_connect(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint8_t *r = x->response;
    if (cmd[1] > 1u) {
        fail(x, ERR_OUT_OF_RANGE);
        return;
    }
    x->connected = 1;
    x->connects++;
    x->locked = x->config.protected_resources;
    x->seed_resource = 0;
    x->mta_text = 0;
    r[1] = (uint8_t)(P2D_XCP_RESOURCE_CALPAG | (x->config.event_count > 0u ? P2D_XCP_RESOURCE_DAQ : 0u));
    r[2] = (uint8_t)(0x80u | 0x40u | x->byte_order); /* OPTIONAL (GET_COMM_MODE_INFO), SLAVE_BLOCK_MODE, AG BYTE */
    r[3] = x->config.max_cto;
    put(x, r + 4, x->config.max_dto, 2);
    r[6] = 1; /* protocol layer version */
    r[7] = 1; /* transport layer version */
    respond(x, 8);
}

static void cmd_get_status(p2d_xcp_t *x)
{
    uint8_t *r = x->response;
    r[1] = x->daq_running ? 0x40u : 0u; /* DAQ_RUNNING */
    r[2] = x->locked;
    r[3] = 0;            /* state number */
    put(x, r + 4, 0, 2); /* session configuration id */
    respond(x, 6);
}

static void cmd_get_comm_mode_info(p2d_xcp_t *x)
{
    uint8_t *r = x->response;
    fill_bytes(r + 1, 0, 6); /* no master block mode, no interleaved mode */
    r[7] = 0x10;             /* driver version 1.0 */
    respond(x, 8);
}

/* point the MTA at a text for UPLOAD */
static void set_mta_text(p2d_xcp_t *x, const char *text, uint32_t bytes)
{
    x->mta_text = text;
    x->mta_text_bytes = bytes;
}

static void cmd_get_id(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint8_t *r = x->response;
    const char *text = cmd[1] == 0u ? x->config.id : (cmd[1] == 1u ? x->config.a2l_name : 0);
    uint32_t bytes = text != 0 ? text_bytes(text) : 0u;
    set_mta_text(x, text, bytes);
    r[1] = 0; /* the text is read by UPLOAD */
    r[2] = 0;
    r[3] = 0;
    put(x, r + 4, bytes, 4);
    respond(x, 8);
}

static void cmd_get_seed(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint8_t *r = x->response;
    uint8_t resource = cmd[2];
    if (cmd[1] == 1u) {
        fail(x, ERR_SEQUENCE); /* the whole seed went in the first part */
        return;
    }
    if (cmd[1] != 0u || (resource & (resource - 1u)) != 0u || (resource & RESOURCES_ALL) == 0u) {
        fail(x, ERR_OUT_OF_RANGE);
        return;
    }
    x->seed_resource = 0;
    if ((x->locked & resource) == 0u) {
        r[1] = 0; /* not protected: no seed */
        respond(x, 2);
        return;
    }
    /* xorshift32 (Marsaglia 2003), stirred with the clock */
    x->seed_state ^= x->config.clock(x->config.user);
    if (x->seed_state == 0u) x->seed_state = 0x9E3779B9u;
    for (uint32_t i = 0; i < x->config.seed_bytes; ++i) {
        x->seed_state ^= x->seed_state << 13;
        x->seed_state ^= x->seed_state >> 17;
        x->seed_state ^= x->seed_state << 5;
        x->seed[i] = (uint8_t)(x->seed_state >> 24);
    }
    x->seed_resource = resource;
    x->key_bytes = 0;
    x->key_received = 0;
    r[1] = x->config.seed_bytes;
    copy_bytes(r + 2, x->seed, x->config.seed_bytes);
    respond(x, (uint16_t)(2u + x->config.seed_bytes));
}

static void disconnect(p2d_xcp_t *x)
{
    stop_all(x);
    x->connected = 0;
    x->seed_resource = 0;
}

static void cmd_unlock(p2d_xcp_t *x, const uint8_t *cmd, uint32_t len)
{
    uint8_t expected[P2D_XCP_KEY_MAX_BYTES];
    uint32_t remaining = cmd[1], chunk = (uint32_t)len - 2u, expected_bytes;
    uint8_t difference = 0;
    fill_bytes(expected, 0, (uint32_t)sizeof expected);
    if (x->seed_resource == 0u) {
        fail(x, ERR_SEQUENCE);
        return;
    }
    if (x->key_received == 0u) {
        if (remaining == 0u || remaining > P2D_XCP_KEY_MAX_BYTES) {
            x->seed_resource = 0;
            fail(x, ERR_OUT_OF_RANGE);
            return;
        }
        x->key_bytes = (uint8_t)remaining;
    } else if (remaining != (uint32_t)x->key_bytes - x->key_received) {
        x->seed_resource = 0;
        fail(x, ERR_SEQUENCE);
        return;
    }
    if (chunk > remaining) chunk = remaining;
    if (chunk > x->config.max_cto - 2u) chunk = x->config.max_cto - 2u;
    if (chunk == 0u) {
        fail(x, ERR_CMD_SYNTAX);
        return;
    }
    copy_bytes(x->key + x->key_received, cmd + 2, chunk);
    x->key_received = (uint8_t)(x->key_received + chunk);
    if (x->key_received == x->key_bytes) {
        expected_bytes = x->config.key(x->config.user, x->seed_resource, x->seed, x->config.seed_bytes, expected);
        /* compare every byte, so that the time taken tells nothing of where a wrong key differs */
        for (uint32_t i = 0; i < x->key_bytes; ++i) difference |= (uint8_t)(x->key[i] ^ expected[i]);
        if (expected_bytes == 0u || expected_bytes > P2D_XCP_KEY_MAX_BYTES || expected_bytes != x->key_bytes ||
            difference != 0u) {
            disconnect(x); /* a wrong key ends the session (XCP 1.x UNLOCK) */
            fail(x, ERR_ACCESS_LOCKED);
            return;
        }
        x->locked = (uint8_t)(x->locked & ~x->seed_resource);
        x->seed_resource = 0;
    }
    x->response[1] = x->locked;
    respond(x, 2);
}

static void cmd_upload(p2d_xcp_t *x, uint32_t address, uint32_t n, bool from_mta)
{
    if (n == 0u) {
        fail(x, ERR_OUT_OF_RANGE);
        return;
    }
    if (from_mta && x->mta_text != 0) {
        if (n > x->mta_text_bytes) {
            fail(x, ERR_OUT_OF_RANGE);
            return;
        }
        copy_bytes(x->response + 1, (const uint8_t *)x->mta_text, n);
        x->mta_text += n;
        x->mta_text_bytes -= n;
    } else {
        if (!read_memory(x, address, n, x->response + 1)) return;
        x->mta = address + n;
        x->mta_text = 0;
    }
    respond(x, (uint16_t)(1u + n));
}

static void cmd_download(p2d_xcp_t *x, const uint8_t *cmd, uint32_t len)
{
    uint32_t n = cmd[1];
    uint16_t index = 0;
    const p2d_xcp_segment_t *s;
    if (x->locked & P2D_XCP_RESOURCE_CALPAG) {
        fail(x, ERR_ACCESS_LOCKED);
        return;
    }
    if (n == 0u || n > x->config.max_cto - 2u) {
        fail(x, ERR_OUT_OF_RANGE); /* no master block mode */
        return;
    }
    if (len < 2u + n) {
        fail(x, ERR_CMD_SYNTAX);
        return;
    }
    s = x->mta_text == 0 ? find_segment(x, x->mta, n, &index) : 0;
    if (s == 0) {
        fail(x, ERR_ACCESS_DENIED);
        return;
    }
    if (s->access != P2D_XCP_CALIBRATION) {
        fail(x, ERR_WRITE_PROTECTED);
        return;
    }
    /* the shadow page: the segment with the new bytes; in force after p2d_xcp_calibrate */
    copy_bytes((uint8_t *)x->config.shadow, (const uint8_t *)s->memory, s->size_bytes);
    copy_bytes((uint8_t *)x->config.shadow + (x->mta - s->address), cmd + 2, n);
    x->commit_segment = index;
    x->commit_bytes = (uint8_t)n;
    x->commit_state = 1;
    x->response_bytes = 0; /* answered by p2d_xcp_calibrate */
}

static void cmd_get_daq_processor_info(p2d_xcp_t *x)
{
    uint8_t *r = x->response;
    uint32_t max_daq = x->config.daq_memory_bytes / (uint32_t)sizeof(xcp_list_t);
    r[1] = 0x01u | 0x02u | 0x10u; /* DAQ_CONFIG_TYPE dynamic, PRESCALER_SUPPORTED, TIMESTAMP_SUPPORTED */
    put(x, r + 2, (uint16_t)(max_daq > 0xFFFFu ? 0xFFFFu : max_daq), 2);
    put(x, r + 4, x->config.event_count, 2);
    r[6] = 0;     /* MIN_DAQ: no predefined lists */
    r[7] = 0x30u; /* DAQ_KEY_BYTE: absolute ODT number, one address extension for all, default optimisation */
    respond(x, 8);
}

static void cmd_get_daq_resolution_info(p2d_xcp_t *x)
{
    uint8_t *r = x->response;
    uint32_t entry_max = (uint32_t)x->config.max_dto - 1u;
    r[1] = 1; /* granularity of an ODT entry [bytes] */
    r[2] = (uint8_t)(entry_max > 255u ? 255u : entry_max);
    r[3] = 1; /* STIM: none */
    r[4] = 0;
    r[5] = (uint8_t)((unsigned)x->config.timestamp_unit << 4 | 0x04u); /* 4-byte timestamps, not fixed */
    put(x, r + 6, x->config.timestamp_ticks, 2);
    respond(x, 8);
}

static void cmd_get_daq_event_info(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint8_t *r = x->response;
    uint16_t index = (uint16_t)get(x, cmd + 2, 2);
    const p2d_xcp_event_t *e;
    if (index >= x->config.event_count) {
        fail(x, ERR_OUT_OF_RANGE);
        return;
    }
    e = &x->config.events[index];
    set_mta_text(x, e->name, text_bytes(e->name));
    r[1] = 0x84u; /* DAQ, consistency per event channel */
    r[2] = 0xFFu; /* any number of DAQ lists */
    r[3] = (uint8_t)x->mta_text_bytes;
    r[4] = e->cycle;
    r[5] = e->cycle_unit;
    r[6] = e->priority;
    respond(x, 7);
}

static void cmd_alloc_daq(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint16_t count = (uint16_t)get(x, cmd + 2, 2);
    void *p;
    if (x->daq_alloc_step != 0u) {
        fail(x, ERR_SEQUENCE);
        return;
    }
    p = daq_alloc(x, count, (uint32_t)sizeof(xcp_list_t));
    if (p == 0) {
        fail(x, ERR_MEMORY_OVERFLOW);
        return;
    }
    x->daq_lists = p;
    x->daq_list_count = count;
    x->daq_alloc_step = 1;
    respond(x, 1);
}

static void cmd_alloc_odt(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint16_t list = (uint16_t)get(x, cmd + 2, 2);
    uint8_t count = cmd[4];
    xcp_list_t *l;
    if (x->daq_alloc_step != 1u && x->daq_alloc_step != 2u) {
        fail(x, ERR_SEQUENCE);
        return;
    }
    if (list >= x->daq_list_count || count == 0u) {
        fail(x, ERR_OUT_OF_RANGE);
        return;
    }
    l = &lists(x)[list];
    if (l->odt_count != 0u) {
        fail(x, ERR_SEQUENCE);
        return;
    }
    if ((uint32_t)x->odt_count + count > ODT_COUNT_MAX ||
        (l->odts = (xcp_odt_t *)daq_alloc(x, count, (uint32_t)sizeof(xcp_odt_t))) == 0) {
        fail(x, ERR_MEMORY_OVERFLOW);
        return;
    }
    l->odt_count = count;
    x->odt_count = (uint16_t)(x->odt_count + count);
    x->daq_alloc_step = 2;
    respond(x, 1);
}

static void cmd_alloc_odt_entry(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint16_t list = (uint16_t)get(x, cmd + 2, 2);
    uint8_t odt = cmd[4], count = cmd[5];
    xcp_odt_t *o;
    if (x->daq_alloc_step != 2u && x->daq_alloc_step != 3u) {
        fail(x, ERR_SEQUENCE);
        return;
    }
    if (list >= x->daq_list_count || odt >= lists(x)[list].odt_count || count == 0u) {
        fail(x, ERR_OUT_OF_RANGE);
        return;
    }
    o = &lists(x)[list].odts[odt];
    if (o->entry_count != 0u) {
        fail(x, ERR_SEQUENCE);
        return;
    }
    if ((o->entries = (xcp_entry_t *)daq_alloc(x, count, (uint32_t)sizeof(xcp_entry_t))) == 0) {
        fail(x, ERR_MEMORY_OVERFLOW);
        return;
    }
    o->entry_count = count;
    x->daq_alloc_step = 3;
    respond(x, 1);
}

static void cmd_set_daq_ptr(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint16_t list = (uint16_t)get(x, cmd + 2, 2);
    uint8_t odt = cmd[4], entry = cmd[5];
    x->daq_ptr_valid = 0;
    if (list >= x->daq_list_count || odt >= lists(x)[list].odt_count || entry >= lists(x)[list].odts[odt].entry_count) {
        fail(x, ERR_OUT_OF_RANGE);
        return;
    }
    if (lists(x)[list].flags & LIST_RUNNING) {
        fail(x, ERR_DAQ_ACTIVE);
        return;
    }
    x->daq_ptr_list = list;
    x->daq_ptr_odt = odt;
    x->daq_ptr_entry = entry;
    x->daq_ptr_valid = 1;
    respond(x, 1);
}

static void cmd_write_daq(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint32_t size = cmd[2], address = get(x, cmd + 4, 4);
    const p2d_xcp_segment_t *s;
    xcp_list_t *l;
    xcp_odt_t *o;
    xcp_entry_t *e;
    if (!x->daq_ptr_valid) {
        fail(x, ERR_SEQUENCE);
        return;
    }
    l = &lists(x)[x->daq_ptr_list];
    o = &l->odts[x->daq_ptr_odt];
    if (l->flags & LIST_RUNNING) {
        fail(x, ERR_DAQ_ACTIVE);
        return;
    }
    if (x->daq_ptr_entry >= o->entry_count || cmd[1] != 0xFFu || size == 0u || size > x->config.max_dto - 1u ||
        cmd[3] != 0u) {
        fail(x, ERR_OUT_OF_RANGE); /* past the ODT's end, a bit offset, a size, an address extension */
        return;
    }
    s = find_segment(x, address, size, 0);
    if (s == 0) {
        fail(x, ERR_ACCESS_DENIED);
        return;
    }
    e = &o->entries[x->daq_ptr_entry];
    if (o->payload_bytes - e->size_bytes + size > x->config.max_dto - 1u) {
        fail(x, ERR_DAQ_CONFIG);
        return;
    }
    o->payload_bytes = o->payload_bytes - e->size_bytes + size;
    e->source = (const uint8_t *)s->memory + (address - s->address);
    e->size_bytes = size;
    x->daq_ptr_entry++;
    respond(x, 1);
}

static void cmd_set_daq_list_mode(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint16_t list = (uint16_t)get(x, cmd + 2, 2), event = (uint16_t)get(x, cmd + 4, 2);
    xcp_list_t *l;
    if (list >= x->daq_list_count || (cmd[1] & ~0x10u) != 0u || event >= x->config.event_count || cmd[6] == 0u) {
        fail(x, ERR_OUT_OF_RANGE); /* only the TIMESTAMP bit; DAQ direction, no PID_OFF; prescaler >= 1 */
        return;
    }
    l = &lists(x)[list];
    if (l->flags & LIST_RUNNING) {
        fail(x, ERR_DAQ_ACTIVE);
        return;
    }
    l->event = event;
    l->prescaler = cmd[6];
    l->flags = (uint8_t)((l->flags & LIST_SELECTED) | LIST_MODE_SET | ((cmd[1] & 0x10u) ? LIST_TIMESTAMP : 0u));
    respond(x, 1);
}

static void start_list(xcp_list_t *l)
{
    l->prescale_count = (uint8_t)(l->prescaler - 1u); /* the first event samples */
    l->flags = (uint8_t)((l->flags & ~LIST_SELECTED) | LIST_RUNNING);
}

static void cmd_start_stop_daq_list(p2d_xcp_t *x, const uint8_t *cmd)
{
    uint16_t list = (uint16_t)get(x, cmd + 2, 2);
    xcp_list_t *l;
    if (list >= x->daq_list_count || cmd[1] > 2u) {
        fail(x, ERR_OUT_OF_RANGE);
        return;
    }
    l = &lists(x)[list];
    if (cmd[1] == 0u) {
        l->flags = (uint8_t)(l->flags & ~LIST_RUNNING);
        l->first_pid = first_pid(x, list);
    } else if (!list_ready(x, list)) {
        fail(x, ERR_DAQ_CONFIG);
        return;
    } else if (cmd[1] == 1u) {
        start_list(l);
    } else {
        l->flags |= LIST_SELECTED;
    }
    update_daq_running(x);
    x->response[1] = l->first_pid;
    respond(x, 2);
}

static void cmd_start_stop_synch(p2d_xcp_t *x, const uint8_t *cmd)
{
    if (cmd[1] > 2u) {
        fail(x, ERR_OUT_OF_RANGE);
        return;
    }
    if (cmd[1] == 0u) {
        stop_all(x);
    } else {
        if (cmd[1] == 1u) {
            for (uint32_t i = 0; i < x->daq_list_count; ++i) {
                if ((lists(x)[i].flags & LIST_SELECTED) && !list_ready(x, i)) {
                    fail(x, ERR_DAQ_CONFIG);
                    return;
                }
            }
        }
        for (uint32_t i = 0; i < x->daq_list_count; ++i) {
            xcp_list_t *l = &lists(x)[i];
            if (!(l->flags & LIST_SELECTED)) continue;
            if (cmd[1] == 1u) {
                start_list(l);
            } else {
                l->flags = (uint8_t)(l->flags & ~(LIST_RUNNING | LIST_SELECTED));
            }
        }
        update_daq_running(x);
    }
    respond(x, 1);
}

static void cmd_free_daq(p2d_xcp_t *x)
{
    stop_all(x);
    x->daq_lists = 0;
    x->daq_list_count = 0;
    x->odt_count = 0;
    x->daq_used_bytes = 0;
    x->daq_alloc_step = 0;
    x->daq_ptr_valid = 0;
    respond(x, 1);
}

static void cmd_get_daq_clock(p2d_xcp_t *x)
{
    uint8_t *r = x->response;
    r[1] = 0; /* legacy format: no trigger information */
    r[2] = 0;
    r[3] = 0;
    put(x, r + 4, x->config.clock(x->config.user), 4);
    respond(x, 8);
}

/* Shortest packet of each command [bytes]; 0: not supported. */
static uint32_t command_bytes(uint8_t pid)
{
    switch (pid) {
    case CMD_DISCONNECT:
    case CMD_GET_STATUS:
    case CMD_SYNCH:
    case CMD_GET_COMM_MODE_INFO:
    case CMD_GET_DAQ_CLOCK:
    case CMD_GET_DAQ_PROCESSOR_INFO:
    case CMD_GET_DAQ_RESOLUTION_INFO:
    case CMD_FREE_DAQ: return 1;
    case CMD_CONNECT:
    case CMD_GET_ID:
    case CMD_UNLOCK:
    case CMD_UPLOAD:
    case CMD_DOWNLOAD:
    case CMD_START_STOP_SYNCH: return 2;
    case CMD_GET_SEED: return 3;
    case CMD_GET_DAQ_EVENT_INFO:
    case CMD_ALLOC_DAQ:
    case CMD_START_STOP_DAQ_LIST: return 4;
    case CMD_ALLOC_ODT: return 5;
    case CMD_ALLOC_ODT_ENTRY:
    case CMD_SET_DAQ_PTR: return 6;
    case CMD_SET_MTA:
    case CMD_SHORT_UPLOAD:
    case CMD_WRITE_DAQ:
    case CMD_SET_DAQ_LIST_MODE: return 8;
    default: return 0;
    }
}

/* Whether a command belongs to the DAQ resource (seed and key). */
static bool is_daq_command(uint8_t pid) { return pid <= CMD_SET_DAQ_PTR && pid >= CMD_ALLOC_ODT_ENTRY; }

static void dispatch(p2d_xcp_t *x, const uint8_t *cmd, uint32_t len)
{
    uint8_t pid = cmd[0];
    uint32_t shortest = command_bytes(pid);
    if (shortest == 0u) {
        fail(x, ERR_CMD_UNKNOWN);
        return;
    }
    if (len < shortest) {
        fail(x, ERR_CMD_SYNTAX);
        return;
    }
    if (is_daq_command(pid) && (x->config.event_count == 0u || (x->locked & P2D_XCP_RESOURCE_DAQ))) {
        fail(x, x->config.event_count == 0u ? ERR_CMD_UNKNOWN : ERR_ACCESS_LOCKED);
        return;
    }
    switch (pid) {
    case CMD_CONNECT: cmd_connect(x, cmd); break;
    case CMD_DISCONNECT:
        disconnect(x);
        respond(x, 1);
        break;
    case CMD_GET_STATUS: cmd_get_status(x); break;
    case CMD_SYNCH: fail(x, ERR_CMD_SYNCH); break;
    case CMD_GET_COMM_MODE_INFO: cmd_get_comm_mode_info(x); break;
    case CMD_GET_ID: cmd_get_id(x, cmd); break;
    case CMD_GET_SEED: cmd_get_seed(x, cmd); break;
    case CMD_UNLOCK: cmd_unlock(x, cmd, len); break;
    case CMD_SET_MTA:
        if (cmd[3] != 0u) {
            fail(x, ERR_OUT_OF_RANGE); /* address extension */
            break;
        }
        x->mta = get(x, cmd + 4, 4);
        x->mta_text = 0;
        respond(x, 1);
        break;
    case CMD_UPLOAD: cmd_upload(x, x->mta, cmd[1], true); break;
    case CMD_SHORT_UPLOAD:
        if (cmd[1] > x->config.max_cto - 1u || cmd[3] != 0u) {
            fail(x, ERR_OUT_OF_RANGE);
            break;
        }
        cmd_upload(x, get(x, cmd + 4, 4), cmd[1], false);
        break;
    case CMD_DOWNLOAD: cmd_download(x, cmd, len); break;
    case CMD_GET_DAQ_CLOCK: cmd_get_daq_clock(x); break;
    case CMD_GET_DAQ_PROCESSOR_INFO: cmd_get_daq_processor_info(x); break;
    case CMD_GET_DAQ_RESOLUTION_INFO: cmd_get_daq_resolution_info(x); break;
    case CMD_GET_DAQ_EVENT_INFO: cmd_get_daq_event_info(x, cmd); break;
    case CMD_FREE_DAQ: cmd_free_daq(x); break;
    case CMD_ALLOC_DAQ: cmd_alloc_daq(x, cmd); break;
    case CMD_ALLOC_ODT: cmd_alloc_odt(x, cmd); break;
    case CMD_ALLOC_ODT_ENTRY: cmd_alloc_odt_entry(x, cmd); break;
    case CMD_SET_DAQ_PTR: cmd_set_daq_ptr(x, cmd); break;
    case CMD_WRITE_DAQ: cmd_write_daq(x, cmd); break;
    case CMD_SET_DAQ_LIST_MODE: cmd_set_daq_list_mode(x, cmd); break;
    case CMD_START_STOP_DAQ_LIST: cmd_start_stop_daq_list(x, cmd); break;
    default: cmd_start_stop_synch(x, cmd); break;
    }
}

void p2d_xcp_command(p2d_xcp_t *x, const uint8_t *packet, uint32_t len)
{
    uint32_t now;
    if (x == 0 || packet == 0 || len == 0u) return;
    now = x->config.clock(x->config.user);
    lock(x);
    if (x->connected || packet[0] == CMD_CONNECT) { /* not connected: silent but for CONNECT */
        x->last_command_ticks = now;
        x->link_silent = 0;
        if (x->commit_state == 1u && (packet[0] == CMD_CONNECT || packet[0] == CMD_SYNCH)) {
            x->commit_state = 0; /* the master gave up waiting: the write is dropped */
        }
        if (x->commit_state != 0u) {
            fail(x, ERR_CMD_BUSY);
        } else {
            dispatch(x, packet, len);
        }
    }
    unlock(x);
}

p2d_xcp_commit_t p2d_xcp_calibrate(p2d_xcp_t *x)
{
    const p2d_xcp_segment_t *s;
    int32_t code;
    if (x == 0) return P2D_XCP_COMMIT_NONE;
    lock(x);
    if (x->commit_state != 1u) {
        unlock(x);
        return P2D_XCP_COMMIT_NONE;
    }
    x->commit_state = 2;
    s = &x->config.segments[x->commit_segment];
    unlock(x);
    code = x->config.commit(x->config.user, x->commit_segment, x->config.shadow);
    lock(x);
    if (code == 0) {
        copy_bytes((uint8_t *)s->memory, (const uint8_t *)x->config.shadow, s->size_bytes);
        x->mta += x->commit_bytes;
        x->commits_applied++;
        respond(x, 1);
    } else {
        x->commit_status = code;
        x->commits_rejected++;
        fail(x, ERR_OUT_OF_RANGE);
    }
    x->commit_state = 0;
    unlock(x);
    return code == 0 ? P2D_XCP_COMMIT_APPLIED : P2D_XCP_COMMIT_REJECTED;
}

bool p2d_xcp_link_check(p2d_xcp_t *x)
{
    uint32_t now;
    bool silent;
    if (x == 0) return false;
    now = x->config.clock(x->config.user);
    lock(x);
    if (x->connected && x->config.link_timeout_ticks > 0u &&
        now - x->last_command_ticks > x->config.link_timeout_ticks) {
        x->link_silent = 1;
    }
    silent = x->link_silent != 0u;
    unlock(x);
    return silent;
}

/* ---------------------------------------------------------------- framing */

void p2d_xcp_frame_init(p2d_xcp_frame_t *f, bool checksum)
{
    if (f == 0) return;
    fill_bytes((uint8_t *)f, 0, (uint32_t)sizeof *f);
    f->checksum = checksum;
}

void p2d_xcp_frame_rx_reset(p2d_xcp_frame_t *f)
{
    if (f == 0) return;
    f->rx_count = 0;
    f->rx_sum = 0;
}

uint32_t p2d_xcp_frame_rx(p2d_xcp_frame_t *f, uint8_t byte)
{
    uint32_t header = P2D_XCP_FRAME_HEADER_BYTES;
    if (f == 0) return 0;
    if (f->rx_count < header) {
        f->rx_header[f->rx_count++] = byte;
        f->rx_sum = (uint8_t)(f->rx_sum + byte);
        if (f->rx_count == header) {
            f->rx_length = (uint16_t)(f->rx_header[0] | f->rx_header[1] << 8);
            if (f->rx_length == 0u || f->rx_length > sizeof f->packet) {
                f->rx_errors++;
                p2d_xcp_frame_rx_reset(f);
            }
        }
        return 0;
    }
    if (f->rx_count < header + f->rx_length) {
        f->packet[f->rx_count - header] = byte;
        f->rx_count++;
        f->rx_sum = (uint8_t)(f->rx_sum + byte);
        if (f->rx_count < header + f->rx_length || f->checksum) return 0;
    } else if (byte != f->rx_sum) {
        f->rx_errors++;
        p2d_xcp_frame_rx_reset(f);
        return 0;
    }
    p2d_xcp_frame_rx_reset(f);
    return f->rx_length;
}

uint32_t p2d_xcp_frame_tx(p2d_xcp_frame_t *f, uint8_t *frame, uint32_t len)
{
    uint32_t n = P2D_XCP_FRAME_HEADER_BYTES + len;
    uint8_t sum = 0;
    if (f == 0 || frame == 0 || len == 0u || len > 0xFFFFu - P2D_XCP_FRAME_HEADER_BYTES) return 0;
    frame[0] = (uint8_t)(len & 0xFFu);
    frame[1] = (uint8_t)(len >> 8);
    frame[2] = (uint8_t)(f->tx_counter & 0xFFu);
    frame[3] = (uint8_t)(f->tx_counter >> 8);
    f->tx_counter++;
    if (!f->checksum) return n;
    for (uint32_t i = 0; i < n; ++i) sum = (uint8_t)(sum + frame[i]);
    frame[n] = sum;
    return n + 1u;
}

/* ---------------------------------------------------------------- CAN */

/* the data lengths of CAN FD above 8 bytes */
static const uint8_t CAN_FD_BYTES[7] = {12, 16, 20, 24, 32, 48, 64};

uint32_t p2d_xcp_can_length(uint32_t len, uint32_t min_bytes)
{
    uint32_t need = len > min_bytes ? len : min_bytes;
    if (len == 0u || need > 64u) return 0;
    if (need <= 8u) return need;
    for (uint32_t i = 0; i < sizeof CAN_FD_BYTES; ++i) {
        if (need <= CAN_FD_BYTES[i]) return CAN_FD_BYTES[i];
    }
    return 0;
}

uint32_t p2d_xcp_can_pad(uint8_t *frame, uint32_t len, uint32_t min_bytes, uint8_t fill)
{
    uint32_t n = p2d_xcp_can_length(len, min_bytes);
    if (frame == 0 || n == 0u) return 0;
    fill_bytes(frame + len, fill, n - len);
    return n;
}

uint8_t p2d_xcp_can_dlc(uint32_t data_bytes)
{
    if (data_bytes <= 8u) return (uint8_t)data_bytes;
    for (uint32_t i = 0; i < sizeof CAN_FD_BYTES; ++i) {
        if (data_bytes == CAN_FD_BYTES[i]) return (uint8_t)(9u + i);
    }
    return 0xFFu;
}

/* ---------------------------------------------------------------- link guard */

p2d_xcp_status_t p2d_xcp_guard_init(p2d_xcp_guard_t *g, const p2d_xcp_guard_config_t *cfg)
{
    float step;
    if (g == 0 || cfg == 0) return P2D_XCP_ERR_NULL;
    if (!isfinite(cfg->Ts_s) || !(cfg->Ts_s > 0.0f)) return P2D_XCP_ERR_GUARD_TS;
    step = cfg->ramp_radps_per_s * cfg->Ts_s;
    if (!isfinite(cfg->ramp_radps_per_s) || !(cfg->ramp_radps_per_s > 0.0f) || !isfinite(step) || !(step > 0.0f)) {
        return P2D_XCP_ERR_GUARD_RAMP;
    }
    if (!isfinite(cfg->hold_s) || !(cfg->hold_s >= 0.0f) || cfg->hold_s / cfg->Ts_s > 16777216.0f) {
        return P2D_XCP_ERR_GUARD_HOLD;
    }
    g->config = *cfg;
    g->ramp_step_radps = step;
    g->hold_samples = (uint32_t)(cfg->hold_s / cfg->Ts_s + 0.5f);
    g->state = P2D_XCP_GUARD_ARMED;
    g->w_ref_radps = 0.0f;
    g->hold_count = 0;
    return P2D_XCP_OK;
}

float p2d_xcp_guard_step(p2d_xcp_guard_t *g, bool silent, float w_cmd_radps, bool *power_on)
{
    float magnitude;
    bool on = true;
    if (g == 0) {
        if (power_on != 0) *power_on = false;
        return 0.0f;
    }
    if (g->state == P2D_XCP_GUARD_ARMED) {
        if (!silent) {
            g->w_ref_radps = w_cmd_radps;
            if (power_on != 0) *power_on = true;
            return w_cmd_radps;
        }
        g->state = P2D_XCP_GUARD_RAMPING;
    }
    switch (g->state) {
    case P2D_XCP_GUARD_RAMPING:
        /* w_ref[k] = sign(w_ref[k-1]) max(|w_ref[k-1]| - ramp Ts, 0); a reference that is not finite stops at once */
        magnitude = fabsf(g->w_ref_radps) - g->ramp_step_radps;
        g->w_ref_radps = magnitude > 0.0f ? copysignf(magnitude, g->w_ref_radps) : 0.0f;
        if (g->w_ref_radps == 0.0f) {
            g->state = P2D_XCP_GUARD_HOLDING;
            g->hold_count = 0;
        }
        break;
    case P2D_XCP_GUARD_HOLDING:
        if (g->hold_count < g->hold_samples) {
            g->hold_count++;
        } else {
            g->state = P2D_XCP_GUARD_STOPPED;
            on = false;
        }
        break;
    default: on = false; break;
    }
    if (power_on != 0) *power_on = on;
    return g->w_ref_radps;
}

void p2d_xcp_guard_reset(p2d_xcp_guard_t *g)
{
    if (g == 0) return;
    g->state = P2D_XCP_GUARD_ARMED;
    g->hold_count = 0;
}
