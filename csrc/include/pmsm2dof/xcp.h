/*
 * pmsm2dof: an XCP slave (ASAM MCD-1 XCP 1.x protocol layer) for measuring
 * and calibrating the drive from a PC: CANape, INCA or pyxcp as the master.
 *
 * Layers, each usable alone:
 *   protocol   p2d_xcp_command takes one command packet (CTO) and queues its
 *              response; p2d_xcp_event samples the DAQ lists of one event into
 *              the DTO queue; p2d_xcp_take hands the next packet to send.
 *   framing    p2d_xcp_frame_*: the LEN/CTR header of XCP on Ethernet (TCP)
 *              and on SxI (UART, HEADER_LEN_CTR_WORD, optional CHECKSUM_BYTE),
 *              with a byte-at-a-time receiver.
 *   CAN        p2d_xcp_can_*: one packet per frame, padded to a CAN (FD) size.
 *
 * Memory. The master reaches memory only through the segments the integrator
 * declares: {XCP address, pointer, size, access}. An access (UPLOAD,
 * SHORT_UPLOAD, DOWNLOAD, an ODT entry) must lie inside one segment; anything
 * else is refused with ERR_ACCESS_DENIED, a write to a measurement segment
 * with ERR_WRITE_PROTECTED. On the MCU the XCP address of a segment is its
 * real address ((uint32_t)(uintptr_t)pointer, what the A2L file lists); on a
 * 64-bit host it is any 32-bit number that the segment table maps to host
 * memory.
 *
 * Calibration. A DOWNLOAD into a calibration segment is written to the shadow
 * page (a copy of the segment), not to the segment. The integrator calls
 * p2d_xcp_calibrate at the start of every speed sample; it hands the whole
 * shadow page to the commit callback, which validates and applies it (e.g.
 * p2d_speed_set_config: validating, bumpless); when the callback accepts, the
 * page is copied into the segment, all at once, and DOWNLOAD is answered
 * positively; when it rejects, the segment and the drive are unchanged, the
 * shadow is dropped and DOWNLOAD is answered ERR_OUT_OF_RANGE (the callback's
 * own code is kept in commit_status). The response waits for the commit, so
 * the master's next command sees the values in force. One DOWNLOAD
 * (max_cto - 2 bytes) is the unit that takes effect at once.
 *
 * DAQ. Dynamic DAQ lists (FREE_DAQ, ALLOC_DAQ, ALLOC_ODT, ALLOC_ODT_ENTRY,
 * SET_DAQ_PTR, WRITE_DAQ, SET_DAQ_LIST_MODE, START_STOP_DAQ_LIST,
 * START_STOP_SYNCH) in the caller's daq_memory; identification field: the
 * absolute ODT number (PID 0..251); per-list prescaler and 4-byte timestamp
 * (clock ticks of the integrator's clock) in the first ODT. The events are the
 * integrator's (e.g. "current" at 20 kHz, "speed" at 2 kHz); p2d_xcp_event
 * samples every running list of the event whose prescaler is due, all its
 * ODTs at once (consistency per event), or none of them when the DTO queue
 * has no room for all (dtos_lost counts those samples).
 *
 * Other commands: CONNECT, DISCONNECT, GET_STATUS, SYNCH, GET_COMM_MODE_INFO,
 * GET_ID (0: the integrator's text, 1: the A2L file name, read by UPLOAD),
 * SET_MTA, UPLOAD (slave block mode when longer than one packet),
 * SHORT_UPLOAD, DOWNLOAD, GET_SEED, UNLOCK, GET_DAQ_PROCESSOR_INFO,
 * GET_DAQ_RESOLUTION_INFO, GET_DAQ_EVENT_INFO, GET_DAQ_CLOCK. Every other
 * command is answered ERR_CMD_UNKNOWN; malformed ones ERR_CMD_SYNTAX or
 * ERR_OUT_OF_RANGE; a resource under seed and key ERR_ACCESS_LOCKED until
 * unlocked. While not connected the slave answers CONNECT only (XCP 1.x).
 * Byte order: the machine's own (reported in CONNECT), address granularity
 * BYTE.
 *
 * Link watchdog: once connected, p2d_xcp_link_check reports a master silent
 * for more than link_timeout_ticks; p2d_xcp_guard_* is the policy the drive
 * applies then (ramp the reference to zero, hold, disable the power stage).
 * Any command feeds it; the integrator ties a run to the master that started
 * it by the count of CONNECTs (connects), since a master that reconnects
 * after a cut, or another one, sends CONNECT first.
 *
 * Concurrency. p2d_xcp_command, p2d_xcp_event, p2d_xcp_calibrate and
 * p2d_xcp_take may run in different contexts (command parser in the main
 * loop, events in the current and speed interrupts, the transmitter in its
 * own interrupt): the slave then needs the integrator's lock/unlock (e.g.
 * save PRIMASK and disable interrupts / restore it; a mutex on a host), which
 * it holds only for short, bounded sections. With every call in one context,
 * lock and unlock may be NULL.
 *
 * Bounded time: a command costs at most one copy of 255 bytes (or of the
 * largest calibration segment, in p2d_xcp_calibrate); an event at most its
 * DAQ lists' entries. Portable C99, no allocation, no global state: all state
 * in p2d_xcp_t and in the caller's buffers.
 */
#ifndef PMSM2DOF_XCP_H
#define PMSM2DOF_XCP_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Bytes of the LEN/CTR header that p2d_xcp_frame_tx writes in front of a packet. */
#define P2D_XCP_FRAME_HEADER_BYTES 4u
/* Longest key (UNLOCK) and seed (GET_SEED) [bytes]. */
#define P2D_XCP_KEY_MAX_BYTES 32u

/* Status of p2d_xcp_init and p2d_xcp_guard_init: each code names one configuration field. */
typedef enum {
    P2D_XCP_OK = 0,
    P2D_XCP_ERR_NULL,             /* a pointer argument is NULL */
    P2D_XCP_ERR_SEGMENTS,         /* segments, segment_count */
    P2D_XCP_ERR_SEGMENT_MEMORY,   /* segments[i].memory */
    P2D_XCP_ERR_SEGMENT_SIZE,     /* segments[i].size_bytes */
    P2D_XCP_ERR_SEGMENT_ACCESS,   /* segments[i].access */
    P2D_XCP_ERR_SEGMENT_OVERLAP,  /* segments[i].address */
    P2D_XCP_ERR_SHADOW,           /* shadow, shadow_bytes */
    P2D_XCP_ERR_COMMIT,           /* commit */
    P2D_XCP_ERR_EVENTS,           /* events, event_count */
    P2D_XCP_ERR_EVENT_NAME,       /* events[i].name */
    P2D_XCP_ERR_EVENT_CYCLE_UNIT, /* events[i].cycle_unit */
    P2D_XCP_ERR_DAQ_MEMORY,       /* daq_memory, daq_memory_bytes */
    P2D_XCP_ERR_QUEUE,            /* queue, queue_bytes */
    P2D_XCP_ERR_MAX_CTO,          /* max_cto */
    P2D_XCP_ERR_MAX_DTO,          /* max_dto */
    P2D_XCP_ERR_CLOCK,            /* clock */
    P2D_XCP_ERR_TIMESTAMP_UNIT,   /* timestamp_unit */
    P2D_XCP_ERR_TIMESTAMP_TICKS,  /* timestamp_ticks */
    P2D_XCP_ERR_LOCK,             /* lock, unlock */
    P2D_XCP_ERR_PROTECTION,       /* protected_resources */
    P2D_XCP_ERR_KEY,              /* key */
    P2D_XCP_ERR_SEED_BYTES,       /* seed_bytes */
    P2D_XCP_ERR_ID,               /* id */
    P2D_XCP_ERR_GUARD_TS,         /* Ts_s (guard) */
    P2D_XCP_ERR_GUARD_RAMP,       /* ramp_radps_per_s */
    P2D_XCP_ERR_GUARD_HOLD,       /* hold_s */
    P2D_XCP_STATUS_COUNT          /* number of codes, not a code */
} p2d_xcp_status_t;

/* Name of the configuration field that a status code rejects ("" for P2D_XCP_OK). */
const char *p2d_xcp_status_param(p2d_xcp_status_t status);

/* Human-readable valid range of that field. */
const char *p2d_xcp_status_range(p2d_xcp_status_t status);

/* What the master may do with a segment. */
typedef enum {
    P2D_XCP_MEASUREMENT = 0, /* read (UPLOAD, DAQ) */
    P2D_XCP_CALIBRATION = 1  /* read, and write through the shadow page and the commit callback */
} p2d_xcp_access_t;

/* A range of memory the master may reach. Segments must not overlap in XCP addresses. */
typedef struct {
    uint32_t address;        /* XCP address of the first byte (the real address on the MCU) */
    void *memory;            /* the first byte in this program's memory */
    uint32_t size_bytes;     /* length [bytes], >= 1, address + size_bytes <= 2^32 */
    p2d_xcp_access_t access; /* measurement or calibration */
} p2d_xcp_segment_t;

/* An event: a point in the program where DAQ lists are sampled (an interrupt). */
typedef struct {
    const char *name;   /* shown by the master (GET_DAQ_EVENT_INFO), 1..255 characters */
    uint8_t cycle;      /* period = cycle * 10^(cycle_unit - 9) s; 0: sporadic */
    uint8_t cycle_unit; /* XCP time unit 0..9: 0 = 1 ns, 3 = 1 us, 6 = 1 ms, 9 = 1 s */
    uint8_t priority;   /* 0 lowest .. 255 highest, for the master's information */
} p2d_xcp_event_t;

/* Resources (CONNECT, GET_STATUS, GET_SEED): bits of protected_resources. */
typedef enum {
    P2D_XCP_RESOURCE_CALPAG = 0x01, /* calibration (DOWNLOAD) */
    P2D_XCP_RESOURCE_DAQ = 0x04     /* data acquisition (the DAQ commands) */
} p2d_xcp_resource_t;

/* The integrator's free-running 32-bit clock of the timestamps and the watchdog [ticks]; it wraps. */
typedef uint32_t (*p2d_xcp_clock_fn)(void *user);

/* Validate and apply a calibration segment's new page (the whole segment): 0 when accepted, else the
   integrator's code (e.g. a p2d_status_t), and then nothing may have changed. */
typedef int32_t (*p2d_xcp_commit_fn)(void *user, uint16_t segment, const void *page);

/* Write the key of the n-byte seed for a resource to key (P2D_XCP_KEY_MAX_BYTES); return its length, 0: none. */
typedef uint8_t (*p2d_xcp_key_fn)(void *user, uint8_t resource, const uint8_t *seed, uint8_t n, uint8_t *key);

/* Enter or leave the section the slave shares with the other contexts (interrupts, threads). */
typedef void (*p2d_xcp_lock_fn)(void *user);

/* Integrator's configuration. The arrays and buffers stay owned by the caller and must outlive the slave. */
typedef struct {
    const p2d_xcp_segment_t *segments; /* the memory the master may reach */
    uint16_t segment_count;            /* 1..65535 */
    void *shadow;                      /* the shadow page: >= the largest calibration segment [bytes] */
    uint32_t shadow_bytes;             /* size of shadow [bytes]; 0 (and NULL) without calibration segments */
    const p2d_xcp_event_t *events;     /* the events, numbered from 0 in p2d_xcp_event */
    uint16_t event_count;              /* 0..65535 (0: no DAQ) */
    void *daq_memory;                  /* DAQ lists, ODTs and entries, allocated by ALLOC_* */
    uint32_t daq_memory_bytes;   /* size of daq_memory [bytes] (32-bit MCU: 20 per list, 12 per ODT, 8 per entry) */
    uint8_t *queue;              /* the DTO queue (each DTO costs its length + 2 bytes) */
    uint32_t queue_bytes;        /* size of queue [bytes], >= max_dto + 2 */
    uint8_t max_cto;             /* longest command or response packet [bytes], 8..255 (8 on CAN) */
    uint16_t max_dto;            /* longest DAQ packet [bytes], 8..65531 */
    uint8_t timestamp_unit;      /* XCP time unit of a clock tick, 0..9 (0 = 1 ns, 3 = 1 us) */
    uint16_t timestamp_ticks;    /* one clock tick = timestamp_ticks * unit, >= 1 */
    uint32_t link_timeout_ticks; /* watchdog: longest silence of a connected master [ticks]; 0: off */
    uint8_t protected_resources; /* P2D_XCP_RESOURCE_* bits locked until UNLOCK; 0: none */
    uint8_t seed_bytes;          /* length of a seed, 1..min(32, max_cto - 2) (with protection) */
    const char *id;              /* GET_ID type 0: identification text (e.g. firmware and build) */
    const char *a2l_name;        /* GET_ID type 1: A2L file name without path and extension, or NULL */
    void *user;                  /* passed to every callback */
    p2d_xcp_clock_fn clock;      /* the clock of timestamps and watchdog */
    p2d_xcp_commit_fn commit;    /* validates and applies calibration pages; NULL without calibration */
    p2d_xcp_key_fn key;          /* computes keys; NULL without protected resources */
    p2d_xcp_lock_fn lock;        /* enters the shared section, or NULL (every call in one context) */
    p2d_xcp_lock_fn unlock;      /* leaves it, or NULL */
} p2d_xcp_config_t;

/* What p2d_xcp_calibrate did. */
typedef enum {
    P2D_XCP_COMMIT_NONE = 0,    /* no write waiting */
    P2D_XCP_COMMIT_APPLIED = 1, /* the commit callback accepted the page: it is in force */
    P2D_XCP_COMMIT_REJECTED = 2 /* the callback rejected it: nothing changed */
} p2d_xcp_commit_t;

/* The slave. All fields are private to xcp.c except the counters marked "read". */
typedef struct {
    p2d_xcp_config_t config;     /* the integrator's configuration */
    uint8_t byte_order;          /* 0: little endian (Intel), 1: big endian (Motorola), as found at init */
    uint8_t connected;           /* 1 between CONNECT and DISCONNECT */
    uint8_t locked;              /* P2D_XCP_RESOURCE_* bits now locked */
    uint8_t link_silent;         /* 1 once the connected master was silent for link_timeout_ticks (read) */
    uint32_t last_command_ticks; /* clock at the last command received [ticks] (read) */
    uint32_t connects;           /* CONNECT commands accepted since init: a new count is a new master (read) */
    /* memory transfer address */
    uint32_t mta;            /* XCP address of the next UPLOAD or DOWNLOAD */
    const char *mta_text;    /* or text of GET_ID or GET_DAQ_EVENT_INFO being read, NULL if none */
    uint32_t mta_text_bytes; /* its bytes left [bytes] */
    /* seed and key */
    uint8_t seed[32];      /* the last seed sent */
    uint8_t key[32];       /* the key received so far */
    uint8_t seed_resource; /* resource of the last GET_SEED, 0: no unlock under way */
    uint8_t key_bytes;     /* announced length of the key [bytes] */
    uint8_t key_received;  /* key bytes received [bytes] */
    uint32_t seed_state;   /* xorshift state of the seeds */
    /* calibration */
    uint8_t commit_state;      /* 0 none, 1 requested, 2 in the callback */
    uint16_t commit_segment;   /* segment of the waiting write */
    uint8_t commit_bytes;      /* length of the waiting DOWNLOAD [bytes] */
    int32_t commit_status;     /* the commit callback's code of the last rejection (read) */
    uint32_t commits_applied;  /* pages taken into force (read) */
    uint32_t commits_rejected; /* pages rejected (read) */
    /* the response to the last command */
    uint8_t response[256];   /* PID and data; an UPLOAD longer than one packet is cut on taking */
    uint16_t response_bytes; /* its length [bytes], 0: none waiting */
    uint16_t response_taken; /* bytes of it already handed out [bytes] */
    /* DAQ */
    void *daq_lists;         /* the lists, at the start of daq_memory */
    uint16_t daq_list_count; /* lists allocated */
    uint16_t odt_count;      /* ODTs allocated, all lists */
    uint32_t daq_used_bytes; /* daq_memory in use [bytes] */
    uint8_t daq_alloc_step;  /* 0 after FREE_DAQ, 1 after ALLOC_DAQ, 2 after ALLOC_ODT, 3 after ALLOC_ODT_ENTRY */
    uint8_t daq_running;     /* 1 while any list runs */
    uint16_t daq_ptr_list;   /* SET_DAQ_PTR: list */
    uint8_t daq_ptr_odt;     /* ODT */
    uint8_t daq_ptr_entry;   /* entry written by the next WRITE_DAQ */
    uint8_t daq_ptr_valid;   /* 1 after a valid SET_DAQ_PTR */
    /* DTO queue: packets as a 2-byte length and the packet, in a ring */
    uint32_t queue_head; /* next byte written */
    uint32_t queue_tail; /* next byte read */
    uint32_t queue_used; /* bytes in the queue [bytes] */
    uint32_t dtos_sent;  /* DTOs handed to the transport (read) */
    uint32_t dtos_lost;  /* samples of a DAQ list dropped for want of room in the queue (read) */
} p2d_xcp_t;

/* Validate cfg and start the slave disconnected, with no DAQ list. On error x is untouched. */
p2d_xcp_status_t p2d_xcp_init(p2d_xcp_t *x, const p2d_xcp_config_t *cfg);

/* Process one command packet (len bytes, PID first) and queue its response. */
void p2d_xcp_command(p2d_xcp_t *x, const uint8_t *packet, uint32_t len);

/* Sample the DAQ lists bound to event number `event` (call it in that event's interrupt). */
void p2d_xcp_event(p2d_xcp_t *x, uint16_t event);

/* At the start of the speed sample: hand a waiting calibration write to the commit callback. */
p2d_xcp_commit_t p2d_xcp_calibrate(p2d_xcp_t *x);

/* The next packet to send (response first, then DTOs), copied to packet; returns its length, 0: none.
   capacity must hold max_cto and max_dto bytes. */
uint32_t p2d_xcp_take(p2d_xcp_t *x, uint8_t *packet, uint32_t capacity);

/* The watchdog: true when the connected master has been silent for more than link_timeout_ticks. Latched
   until the next command; call it at least once per clock wrap (every speed sample). */
bool p2d_xcp_link_check(p2d_xcp_t *x);

/*
 * Framing on a byte stream, XCP on Ethernet (TCP) and on SxI (UART):
 *   LEN (2 bytes, little endian: packet length) CTR (2 bytes, little endian) packet [CS]
 * CTR counts the frames sent by each side; CS (SxI CHECKSUM_BYTE, optional) is
 * the sum modulo 256 of every byte before it. The receiver takes one byte at a
 * time; a frame with LEN 0 or above 255, or a wrong checksum, is dropped and
 * counted. After a dropped frame the receiver reads the next byte as the start
 * of a header: on a UART, call p2d_xcp_frame_rx_reset at a gap in the stream
 * (idle line) to resynchronise.
 */
typedef struct {
    bool checksum;        /* a checksum byte ends each frame (SxI CHECKSUM_BYTE) */
    uint16_t tx_counter;  /* CTR of the next frame sent */
    uint8_t rx_header[4]; /* header being received */
    uint16_t rx_length;   /* LEN of the frame being received [bytes] */
    uint16_t rx_count;    /* bytes of the frame received so far, header included [bytes] */
    uint8_t rx_sum;       /* sum of its bytes so far, modulo 256 */
    uint8_t packet[255];  /* the last complete packet */
    uint32_t rx_errors;   /* frames dropped (read) */
} p2d_xcp_frame_t;

/* Start a link with no frame received and CTR 0; checksum: a checksum byte ends each frame both ways. */
void p2d_xcp_frame_init(p2d_xcp_frame_t *f, bool checksum);

/* One received byte; returns the length of a packet complete in f->packet (valid until the next call), else 0. */
uint32_t p2d_xcp_frame_rx(p2d_xcp_frame_t *f, uint8_t byte);

/* Forget a partly received frame. */
void p2d_xcp_frame_rx_reset(p2d_xcp_frame_t *f);

/* Frame a packet of len bytes placed at frame + P2D_XCP_FRAME_HEADER_BYTES: writes the header in front of it
   and the checksum (if any) after it; returns the frame's length [bytes]. */
uint32_t p2d_xcp_frame_tx(p2d_xcp_frame_t *f, uint8_t *frame, uint32_t len);

/* XCP on CAN: one packet per frame. The data length of the frame for a packet of len bytes: the smallest CAN
   data length (0..8, then CAN FD 12, 16, 20, 24, 32, 48, 64) that holds max(len, min_bytes); min_bytes 8 or the
   CAN FD MAX_DLC when the bus requires full frames (XCP MAX_DLC_REQUIRED), else 0. Returns 0 when len is 0 or
   either is above 64. */
uint32_t p2d_xcp_can_length(uint32_t len, uint32_t min_bytes);

/* Pad a packet of len bytes at frame to its CAN data length (p2d_xcp_can_length) with fill; returns that length. */
uint32_t p2d_xcp_can_pad(uint8_t *frame, uint32_t len, uint32_t min_bytes, uint8_t fill);

/* The DLC code of a CAN (FD) data length: 0..8 as is, 12 -> 9, 16 -> 10, 20 -> 11, 24 -> 12, 32 -> 13,
   48 -> 14, 64 -> 15; 0xFF for a length that no DLC codes. */
uint8_t p2d_xcp_can_dlc(uint32_t data_bytes);

/*
 * The drive's reaction to a silent master (link guard), once per speed sample:
 *   ARMED    the master's reference passes: w_ref[k] = w_cmd[k]; power on.
 *   RAMPING  from the sample the link goes silent on, the reference moves to
 *            zero by at most ramp_radps_per_s Ts_s per sample:
 *              w_ref[k] = sign(w_ref[k-1]) max(|w_ref[k-1]| - ramp_radps_per_s Ts_s, 0)
 *            (the master's reference is ignored from then on);
 *   HOLDING  w_ref = 0 for round(hold_s / Ts_s) samples, power on, so that the
 *            speed controller brakes the rotor;
 *   STOPPED  w_ref = 0, power stage disabled; latched until p2d_xcp_guard_reset
 *            (an explicit re-enable by the operator, not the link's return).
 */
typedef struct {
    float Ts_s;             /* period of p2d_xcp_guard_step (the speed sample) [s], finite and > 0 */
    float ramp_radps_per_s; /* deceleration of the reference after a trip [rad/s^2], finite and > 0 */
    float hold_s;           /* zero reference before the power stage is disabled [s], finite, >= 0, <= 2^24 Ts_s */
} p2d_xcp_guard_config_t;

/* States of the link guard (above). */
typedef enum {
    P2D_XCP_GUARD_ARMED = 0,
    P2D_XCP_GUARD_RAMPING = 1,
    P2D_XCP_GUARD_HOLDING = 2,
    P2D_XCP_GUARD_STOPPED = 3
} p2d_xcp_guard_state_t;

/* The link guard: its configuration, precomputed steps and state. */
typedef struct {
    p2d_xcp_guard_config_t config; /* as given to p2d_xcp_guard_init */
    float ramp_step_radps;         /* ramp_radps_per_s Ts_s: the reference's change per sample [rad/s] */
    uint32_t hold_samples;         /* round(hold_s / Ts_s) [samples] */
    p2d_xcp_guard_state_t state;   /* see above */
    float w_ref_radps;             /* the reference of the last sample [rad/s] */
    uint32_t hold_count;           /* samples held so far [samples] */
} p2d_xcp_guard_t;

/* Validate cfg and arm the guard (state ARMED, reference 0). On error g is untouched. */
p2d_xcp_status_t p2d_xcp_guard_init(p2d_xcp_guard_t *g, const p2d_xcp_guard_config_t *cfg);

/* One speed sample: silent from p2d_xcp_link_check, w_cmd_radps the master's reference. Returns the reference to
   apply [rad/s] and writes whether the power stage may stay on. */
float p2d_xcp_guard_step(p2d_xcp_guard_t *g, bool silent, float w_cmd_radps, bool *power_on);

/* Re-arm after a stop (the operator's explicit re-enable). */
void p2d_xcp_guard_reset(p2d_xcp_guard_t *g);

#ifdef __cplusplus
}
#endif

#endif /* PMSM2DOF_XCP_H */
