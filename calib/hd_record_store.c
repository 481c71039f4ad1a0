/* hd_record_store: see hd_record_store.h and docs/reference/records.md. */
#include "hd_record_store.h"

#include <stdbool.h>
#include <string.h>

/* ------------------------------------------------------------ primitives */

uint32_t hd_crc32_update(uint32_t crc, const void *data, size_t len)
{
    const uint8_t *p = (const uint8_t *)data;
    crc = ~crc;
    for (size_t i = 0; i < len; ++i) {
        crc ^= p[i];
        for (unsigned b = 0; b < 8u; ++b) {
            /* Reflected polynomial 0xEDB88320 (IEEE 802.3). */
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
        }
    }
    return ~crc;
}

uint32_t hd_crc32(const void *data, size_t len)
{
    return hd_crc32_update(0u, data, len);
}

void hd_le_put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)(v >> 8);
}

void hd_le_put_u32(uint8_t *p, uint32_t v)
{
    for (unsigned i = 0; i < 4u; ++i) {
        p[i] = (uint8_t)(v >> (8u * i));
    }
}

void hd_le_put_f32(uint8_t *p, float v)
{
    uint32_t bits;
    memcpy(&bits, &v, sizeof bits); /* IEEE-754 binary32 on every target we build */
    hd_le_put_u32(p, bits);
}

uint16_t hd_le_get_u16(const uint8_t *p)
{
    return (uint16_t)((unsigned)p[0] | ((unsigned)p[1] << 8));
}

uint32_t hd_le_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

float hd_le_get_f32(const uint8_t *p)
{
    uint32_t bits = hd_le_get_u32(p);
    float v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

/* ------------------------------------------------------------- one copy */

typedef struct {
    uint8_t kind;
    uint16_t version;
    uint16_t offset;
    uint16_t length;
    uint32_t crc;
} entry_t;

typedef enum { COPY_VALID, COPY_BLANK, COPY_BAD, COPY_IO } copy_state_t;

typedef struct {
    copy_state_t state;
    size_t base;          /* byte offset of this half */
    uint32_t sequence;
    uint8_t count;
    entry_t entries[HD_STORE_MAX_RECORDS];
} copy_t;

#define DIR_END(n) (HD_STORE_HEADER_BYTES + HD_STORE_ENTRY_BYTES * (size_t)(n))
#define HEADER_MAX (DIR_END(HD_STORE_MAX_RECORDS) + 4u)

static bool io_ok(const hd_store_io_t *io)
{
    return io != NULL && io->read != NULL && io->size >= HD_STORE_MIN_SIZE;
}

static bool all_erased(const uint8_t *p, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        if (p[i] != 0xFFu) {
            return false;
        }
    }
    return true;
}

static bool entry_fits(const entry_t *e, size_t image_len, size_t dir_end)
{
    return e->offset >= dir_end && (size_t)e->offset + e->length <= image_len;
}

/* Reads and checks the header and directory of the half at `base`. */
static void read_copy(const hd_store_io_t *io, size_t base, copy_t *c)
{
    uint8_t h[HEADER_MAX];
    memset(c, 0, sizeof *c);
    c->base = base;
    if (io->read(io->ctx, base, h, sizeof h) != 0) {
        c->state = COPY_IO;
        return;
    }
    uint8_t n = h[12];
    if (hd_le_get_u32(h) != HD_STORE_MAGIC) {
        c->state = all_erased(h, sizeof h) ? COPY_BLANK : COPY_BAD;
        return;
    }
    size_t image_len = hd_le_get_u16(h + 6);
    if (hd_le_get_u16(h + 4) != HD_STORE_FORMAT || n > HD_STORE_MAX_RECORDS ||
        image_len > io->size / 2u || image_len > HD_STORE_IMAGE_MAX ||
        image_len < DIR_END(n) + 4u ||
        hd_le_get_u32(h + DIR_END(n)) != hd_crc32(h + 4, DIR_END(n) - 4u)) {
        c->state = COPY_BAD;
        return;
    }
    c->sequence = hd_le_get_u32(h + 8);
    c->count = n;
    for (uint8_t i = 0; i < n; ++i) {
        const uint8_t *p = h + DIR_END(i);
        entry_t *e = &c->entries[i];
        e->kind = p[0];
        e->version = hd_le_get_u16(p + 2);
        e->offset = hd_le_get_u16(p + 4);
        e->length = hd_le_get_u16(p + 6);
        e->crc = hd_le_get_u32(p + 8);
        if (!entry_fits(e, image_len, DIR_END(n) + 4u)) {
            c->state = COPY_BAD;
            return;
        }
    }
    c->state = COPY_VALID;
}

static const entry_t *find(const copy_t *c, uint8_t kind)
{
    if (c->state != COPY_VALID) {
        return NULL;
    }
    for (uint8_t i = 0; i < c->count; ++i) {
        if (c->entries[i].kind == kind) {
            return &c->entries[i];
        }
    }
    return NULL;
}

/* Serial-number arithmetic: survives the 2^32 wrap of the sequence. */
static bool newer(uint32_t a, uint32_t b)
{
    return (int32_t)(a - b) > 0;
}

/* Reads both halves; c[0] is the newest valid one (if any). */
static void read_both(const hd_store_io_t *io, copy_t c[2])
{
    read_copy(io, 0u, &c[0]);
    read_copy(io, io->size / 2u, &c[1]);
    bool swap = (c[1].state == COPY_VALID &&
                 (c[0].state != COPY_VALID || newer(c[1].sequence, c[0].sequence)));
    if (swap) {
        copy_t t = c[0];
        c[0] = c[1];
        c[1] = t;
    }
}

/* Reads a payload into buf and checks its CRC. */
static bool read_payload(const hd_store_io_t *io, const copy_t *c, const entry_t *e, uint8_t *buf)
{
    return io->read(io->ctx, c->base + e->offset, buf, e->length) == 0 &&
           hd_crc32(buf, e->length) == e->crc;
}

/* Checks a payload's CRC without a buffer of its size, a chunk at a time. */
static bool payload_intact(const hd_store_io_t *io, const copy_t *c, const entry_t *e)
{
    uint8_t chunk[64];
    uint32_t crc = 0u;
    for (size_t off = 0; off < e->length; off += sizeof chunk) {
        size_t n = e->length - off < sizeof chunk ? e->length - off : sizeof chunk;
        if (io->read(io->ctx, c->base + e->offset + off, chunk, n) != 0) {
            return false;
        }
        crc = hd_crc32_update(crc, chunk, n);
    }
    return crc == e->crc;
}

/* ------------------------------------------------------------------ load */

hd_record_status_t hd_store_load(const hd_store_io_t *io, uint8_t kind, uint16_t version,
                                 uint8_t *buf, size_t cap, size_t *len, uint32_t *sequence,
                                 uint16_t *stored_version)
{
    if (!io_ok(io) || buf == NULL || len == NULL) {
        return HD_RECORD_IO;
    }
    copy_t c[2];
    read_both(io, c);
    if (c[0].state != COPY_VALID) {
        if (c[0].state == COPY_IO || c[1].state == COPY_IO) {
            return HD_RECORD_IO;
        }
        return (c[0].state == COPY_BLANK && c[1].state == COPY_BLANK) ? HD_RECORD_MISSING
                                                                     : HD_RECORD_CORRUPT;
    }
    const entry_t *e = find(&c[0], kind);
    if (e == NULL) {
        return HD_RECORD_MISSING; /* the newest copy says it does not exist */
    }
    /* The other copy counts as damaged if it is neither valid nor blank, or
     * if it holds this record with a bad payload. */
    bool other_bad = c[1].state == COPY_BAD || c[1].state == COPY_IO;
    for (unsigned i = 0; i < 2u; ++i) {
        const entry_t *ei = (i == 0u) ? e : find(&c[1], kind);
        if (ei == NULL) {
            break;
        }
        if (ei->version != version) {
            if (i == 0u) {
                if (stored_version != NULL) {
                    *stored_version = ei->version;
                }
                return HD_RECORD_BAD_VERSION;
            }
            break; /* an older copy of another version is no fallback */
        }
        if (ei->length > cap) {
            return HD_RECORD_CORRUPT;
        }
        if (read_payload(io, &c[i], ei, buf)) {
            if (i == 0u && !other_bad && c[1].state == COPY_VALID) {
                const entry_t *eo = find(&c[1], kind);
                other_bad = eo != NULL && !payload_intact(io, &c[1], eo);
            }
            *len = ei->length;
            if (sequence != NULL) {
                *sequence = c[i].sequence;
            }
            return (i == 0u && !other_bad) ? HD_RECORD_OK : HD_RECORD_ONE_COPY_BAD;
        }
        other_bad = true; /* this payload was bad: try the other copy */
    }
    return HD_RECORD_CORRUPT;
}

/* ------------------------------------------------------------------ save */

typedef struct {
    uint8_t *image;
    size_t cap;
    size_t used;   /* bytes of payload area used, from data_start */
    size_t data_start;
    uint8_t count;
} builder_t;

static bool add_entry(builder_t *b, uint8_t kind, uint16_t version, const uint8_t *payload,
                      size_t len)
{
    size_t at = b->data_start + b->used;
    if (b->count >= HD_STORE_MAX_RECORDS || at + len > b->cap || len > 0xFFFFu) {
        return false;
    }
    uint8_t *e = b->image + DIR_END(b->count);
    memset(e, 0, HD_STORE_ENTRY_BYTES);
    e[0] = kind;
    hd_le_put_u16(e + 2, version);
    hd_le_put_u16(e + 4, (uint16_t)at);
    hd_le_put_u16(e + 6, (uint16_t)len);
    hd_le_put_u32(e + 8, hd_crc32(payload, len));
    if (len > 0u) {
        memmove(b->image + at, payload, len);
    }
    b->used += len;
    b->count++;
    return true;
}

/* Copies every record but `skip` from its newest intact copy into the
 * builder.  The payload is read into the image area first, then checked. */
static bool carry_forward(const hd_store_io_t *io, const copy_t c[2], uint8_t skip, builder_t *b)
{
    for (uint8_t i = 0; i < c[0].count; ++i) {
        const entry_t *e = &c[0].entries[i];
        if (e->kind == skip) {
            continue;
        }
        size_t at = b->data_start + b->used;
        if (at + e->length > b->cap) {
            return false;
        }
        uint8_t *dst = b->image + at;
        bool ok = read_payload(io, &c[0], e, dst);
        if (!ok) {
            const entry_t *eo = find(&c[1], e->kind);
            ok = eo != NULL && eo->version == e->version && eo->length <= b->cap - at &&
                 read_payload(io, &c[1], eo, dst);
            e = ok ? eo : e;
        }
        /* A record with no intact copy anywhere is dropped, not copied bad. */
        if (ok && !add_entry(b, e->kind, e->version, dst, e->length)) {
            return false;
        }
    }
    return true;
}

static bool write_image(const hd_store_io_t *io, size_t base, const uint8_t *image, size_t len)
{
    if (io->erase(io->ctx, base, io->size / 2u) != 0 ||
        io->write(io->ctx, base + 4u, image + 4, len - 4u) != 0 ||
        io->write(io->ctx, base, image, 4u) != 0) {
        return false;
    }
    uint8_t check[64];
    for (size_t off = 0; off < len; off += sizeof check) {
        size_t n = len - off < sizeof check ? len - off : sizeof check;
        if (io->read(io->ctx, base + off, check, n) != 0 || memcmp(check, image + off, n) != 0) {
            return false;
        }
    }
    return true;
}

hd_record_status_t hd_store_save(const hd_store_io_t *io, uint8_t kind, uint16_t version,
                                 const uint8_t *payload, size_t len)
{
    if (!io_ok(io) || io->write == NULL || io->erase == NULL || io->work == NULL ||
        io->work_size < HD_STORE_IMAGE_MAX || (payload == NULL && len > 0u)) {
        return HD_RECORD_IO;
    }
    copy_t c[2];
    read_both(io, c);
    if (c[0].state == COPY_IO || c[1].state == COPY_IO) {
        return HD_RECORD_IO;
    }
    /* The directory size is known once the records are: reserve room for
     * all slots, then place payloads after the largest possible directory. */
    builder_t b = {io->work, HD_STORE_IMAGE_MAX, 0u, DIR_END(HD_STORE_MAX_RECORDS) + 4u, 0u};
    memset(b.image, 0, b.data_start);
    if (!carry_forward(io, c, kind, &b)) {
        return HD_RECORD_IO;
    }
    if (payload != NULL && !add_entry(&b, kind, version, payload, len)) {
        return HD_RECORD_IO;
    }
    size_t image_len = b.data_start + b.used;
    uint32_t seq = (c[0].state == COPY_VALID) ? c[0].sequence + 1u : 1u;
    hd_le_put_u32(b.image, HD_STORE_MAGIC);
    hd_le_put_u16(b.image + 4, (uint16_t)HD_STORE_FORMAT);
    hd_le_put_u16(b.image + 6, (uint16_t)image_len);
    hd_le_put_u32(b.image + 8, seq);
    b.image[12] = b.count;
    /* Unused directory slots stay zero; the CRC follows the used ones. */
    hd_le_put_u32(b.image + DIR_END(b.count), hd_crc32(b.image + 4, DIR_END(b.count) - 4u));
    /* Never touch the newest valid copy: write the other half. */
    size_t target = (c[0].state == COPY_VALID) ? (c[0].base == 0u ? io->size / 2u : 0u) : 0u;
    return write_image(io, target, b.image, image_len) ? HD_RECORD_OK : HD_RECORD_IO;
}
