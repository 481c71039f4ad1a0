/* hal_moteus: see hal_moteus.h.  Subframe byte: bits 7..4 the kind (0x0 write,
 * 0x1 read, 0x2 reply), bits 3..2 the type (int8, int16, int32, float),
 * bits 1..0 the count (0: a count byte follows); then the register (a
 * varuint, < 128 here) and, for writes and replies, the values, LE. */
#include "hal_moteus.h"

#include <math.h> /* NAN: a compiler builtin, no libm call */
#include <string.h>

#include "hd_record_store.h" /* little-endian helpers */

#define REG_MODE 0x000u
#define REG_POSITION 0x001u
#define REG_VELOCITY 0x002u
#define REG_TORQUE 0x003u
#define REG_VOLTAGE 0x00Du
#define REG_TEMPERATURE 0x00Eu
#define REG_FAULT 0x00Fu
#define REG_COMMAND_POSITION 0x020u

#define T_INT8 0u
#define T_INT16 1u
#define T_INT32 2u
#define T_FLOAT 3u

typedef struct {
    uint8_t *buf;
    size_t cap, n;
    bool ok;
} writer_t;

static writer_t writer(uint8_t *buf, size_t cap)
{
    return (writer_t){buf, cap, 0u, buf != NULL};
}

static void put(writer_t *w, uint8_t b)
{
    if (w->n < w->cap) {
        w->buf[w->n++] = b;
    } else {
        w->ok = false;
    }
}

static void header(writer_t *w, unsigned kind, unsigned type, unsigned count, unsigned reg)
{
    if (count <= 3u) {
        put(w, (uint8_t)(kind << 4 | type << 2 | count));
    } else {
        put(w, (uint8_t)(kind << 4 | type << 2));
        put(w, (uint8_t)count);
    }
    put(w, (uint8_t)reg);
}

static void put_f32(writer_t *w, float v)
{
    uint8_t b[4];
    hd_le_put_f32(b, v);
    for (int i = 0; i < 4; i++) {
        put(w, b[i]);
    }
}

/* moteus's default query: mode (int8), position, velocity, torque (float),
 * voltage, temperature, fault (int8). */
static void default_query(writer_t *w)
{
    header(w, 1u, T_INT8, 1u, REG_MODE);
    header(w, 1u, T_FLOAT, 3u, REG_POSITION);
    header(w, 1u, T_INT8, 3u, REG_VOLTAGE);
}

size_t hal_moteus_encode_torque(float torque_nm, bool query, uint8_t *buf, size_t cap)
{
    writer_t w = writer(buf, cap);
    header(&w, 0u, T_INT8, 1u, REG_MODE);
    put(&w, (uint8_t)HAL_MOTEUS_MODE_POSITION);
    /* position (NaN: none), velocity 0, feed-forward torque, kp_scale 0, kd_scale 0 */
    header(&w, 0u, T_FLOAT, 5u, REG_COMMAND_POSITION);
    put_f32(&w, NAN);
    put_f32(&w, 0.0f);
    put_f32(&w, torque_nm);
    put_f32(&w, 0.0f);
    put_f32(&w, 0.0f);
    if (query) {
        default_query(&w);
    }
    return w.ok ? w.n : 0u;
}

size_t hal_moteus_encode_stop(uint8_t *buf, size_t cap)
{
    writer_t w = writer(buf, cap);
    header(&w, 0u, T_INT8, 1u, REG_MODE);
    put(&w, (uint8_t)HAL_MOTEUS_MODE_STOPPED);
    return w.ok ? w.n : 0u;
}

int hal_moteus_frame(uint8_t dest, uint8_t source, bool reply, const uint8_t *buf, size_t n,
                     hal_can_frame_t *f)
{
    static const uint8_t fd_len[] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64};
    size_t len = 0u;
    for (size_t i = 0; i < sizeof fd_len && len < n; i++) {
        len = fd_len[i];
    }
    if (n > HAL_CAN_MAX_DATA || len < n) {
        return HAL_ERR_RANGE;
    }
    memset(f, 0, sizeof *f);
    f->id = (reply ? 0x8000u : 0u) | (uint32_t)source << 8 | dest;
    f->flags = HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_FD;
    f->len = (uint8_t)len;
    memcpy(f->data, buf, n);
    memset(&f->data[n], 0x50, len - n);
    return HAL_OK;
}

/* A value of a type, scaled as moteus documents for these registers. */
static float scaled(unsigned reg, unsigned type, const uint8_t *p)
{
    static const float int8_scale[16] = {[REG_TORQUE] = 0.5f, [REG_VOLTAGE] = 0.5f,
                                         [REG_TEMPERATURE] = 1.0f, [REG_POSITION] = 0.01f,
                                         [REG_VELOCITY] = 0.1f};
    static const float int16_scale[16] = {[REG_TORQUE] = 0.01f, [REG_VOLTAGE] = 0.1f,
                                          [REG_TEMPERATURE] = 0.1f, [REG_POSITION] = 0.0001f,
                                          [REG_VELOCITY] = 0.00025f};
    static const float int32_scale[16] = {[REG_TORQUE] = 0.001f, [REG_VOLTAGE] = 0.001f,
                                          [REG_TEMPERATURE] = 0.001f, [REG_POSITION] = 0.00001f,
                                          [REG_VELOCITY] = 0.00001f};
    const bool raw = reg == REG_MODE || reg == REG_FAULT;
    switch (type) {
    case T_INT8: return (float)(int8_t)p[0] * (raw ? 1.0f : int8_scale[reg]);
    case T_INT16: return (float)(int16_t)hd_le_get_u16(p) * (raw ? 1.0f : int16_scale[reg]);
    case T_INT32: return (float)(int32_t)hd_le_get_u32(p) * (raw ? 1.0f : int32_scale[reg]);
    default: return hd_le_get_f32(p);
    }
}

static void store(hal_moteus_reply_t *out, unsigned reg, float v)
{
    switch (reg) {
    case REG_MODE: out->have_mode = true; out->mode = (uint8_t)v; break;
    case REG_POSITION: out->position_rev = v; break;
    case REG_VELOCITY: out->velocity_rev_s = v; break;
    case REG_TORQUE: out->torque_nm = v; break;
    case REG_VOLTAGE: out->voltage_v = v; break;
    case REG_TEMPERATURE: out->temperature_c = v; break;
    case REG_FAULT: out->fault = (uint32_t)v; break;
    default: break;
    }
}

int hal_moteus_parse_reply(const uint8_t *buf, size_t n, hal_moteus_reply_t *out)
{
    static const size_t size_of[4] = {1u, 2u, 4u, 4u};
    size_t i = 0u;
    while (i < n) {
        const uint8_t h = buf[i++];
        if (h == 0x50u || h == 0x00u) {
            continue; /* padding, NOP */
        }
        if ((h >> 4) != 2u || i >= n) {
            return HAL_ERR_FORMAT;
        }
        const unsigned type = (h >> 2) & 3u;
        unsigned count = h & 3u;
        if (count == 0u) {
            count = buf[i++];
        }
        if (i >= n || (buf[i] & 0x80u) != 0u) {
            return HAL_ERR_FORMAT; /* registers >= 128 are not ours */
        }
        unsigned reg = buf[i++];
        if (count > n || i + count * size_of[type] > n) {
            return HAL_ERR_FORMAT;
        }
        for (unsigned k = 0; k < count; k++, reg++, i += size_of[type]) {
            if (reg < 16u) {
                store(out, reg, scaled(reg, type, &buf[i]));
            }
        }
    }
    return HAL_OK;
}

void hal_moteus_init(hal_moteus_t *d, const hal_can_t *bus, uint8_t dest, uint8_t source,
                     float kt_nm_per_a)
{
    memset(d, 0, sizeof *d);
    d->bus = bus;
    d->dest = dest;
    d->source = source;
    d->kt_nm_per_a = kt_nm_per_a;
    d->last.voltage_v = d->last.temperature_c = NAN;
}

static int send_bytes(const hal_moteus_t *d, const uint8_t *buf, size_t n, bool reply)
{
    hal_can_frame_t f;
    if (n == 0u || d->bus == NULL || d->bus->send == NULL ||
        hal_moteus_frame(d->dest, d->source, reply, buf, n, &f) != HAL_OK) {
        return HAL_ERR_IO;
    }
    return d->bus->send(d->bus->ctx, &f);
}

static int mo_enable(void *ctx, bool on)
{
    hal_moteus_t *d = ctx;
    d->enabled = on;
    if (on) {
        return HAL_OK;
    }
    uint8_t buf[8];
    return send_bytes(d, buf, hal_moteus_encode_stop(buf, sizeof buf), false);
}

static int mo_command(void *ctx, float current_a)
{
    hal_moteus_t *d = ctx;
    if (!(current_a - current_a == 0.0f)) {
        return HAL_ERR_RANGE;
    }
    uint8_t buf[48];
    return send_bytes(d, buf, hal_moteus_encode_torque(current_a * d->kt_nm_per_a, true, buf, sizeof buf),
                      true);
}

static int mo_status(void *ctx, hal_drive_status_t *out)
{
    hal_moteus_t *d = ctx;
    if (d->age_ticks < UINT32_MAX) {
        d->age_ticks++;
    }
    for (unsigned i = 0; i < HAL_MOTEUS_RX_PER_CALL && d->bus != NULL && d->bus->recv != NULL; i++) {
        hal_can_frame_t f;
        if (d->bus->recv(d->bus->ctx, &f) != HAL_OK) {
            break;
        }
        /* a reply to us: source = the moteus, destination = us */
        if ((f.id & 0xFFu) == d->source && ((f.id >> 8) & 0x7Fu) == d->dest &&
            hal_moteus_parse_reply(f.data, f.len, &d->last) == HAL_OK) {
            d->age_ticks = 0u;
        }
    }
    *out = (hal_drive_status_t){
        .enabled = d->last.have_mode && d->last.mode == HAL_MOTEUS_MODE_POSITION,
        .fault = (d->last.have_mode && d->last.mode == HAL_MOTEUS_MODE_FAULT) || d->last.fault != 0u,
        .fault_code = d->last.fault,
        .bus_voltage_v = d->last.voltage_v,
        .temperature_c = d->last.temperature_c,
        .current_a = NAN,
        .age_ticks = d->last.have_mode ? d->age_ticks : UINT32_MAX,
    };
    return HAL_OK;
}

void hal_moteus_bind(hal_moteus_t *d, hal_t *hal)
{
    hal->actuator = (hal_actuator_t){d, mo_enable, mo_command, mo_status};
}
