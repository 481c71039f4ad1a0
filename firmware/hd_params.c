/* hd_params: see hd_params.h; the rows are in hd_params.def. */
#include "hd_params.h"

#include <math.h> /* isfinite: a builtin, no libm call */
#include <stddef.h>
#include <string.h>

#include "hd_record_store.h" /* hd_crc32, little-endian helpers */

/* The column words of hd_params.def. */
#define F32 HD_PT_F32
#define U32 HD_PT_U32
#define U16 HD_PT_U16
#define U8 HD_PT_U8
#define BOOL HD_PT_BOOL
#define LIVE HD_PF_LIVE
#define REBUILD HD_PF_REBUILD
#define RO HD_PF_RO
#define CONFIG HD_PF_CONFIG
#define CALIB HD_PF_CALIB
#define LO_OPEN HD_PF_LO_OPEN
#define LIB NAN

#define SIZE_OF_F32 4u
#define SIZE_OF_U32 4u
#define SIZE_OF_U16 2u
#define SIZE_OF_U8 1u
#define SIZE_OF_BOOL 1u

/* A row's type must match its field's size. */
#define HD_PARAM(id, NAME, key, type, field, dflt, lo, hi, flags, unit, doc) \
    _Static_assert(sizeof(((hd_fw_config_t *)0)->field) == SIZE_OF_##type, #NAME ": type/field size");
#include "hd_params.def"

static const hd_param_info_t TABLE[] = {
#define HD_PARAM(id, NAME, key, type, field, dflt, lo, hi, flags, unit, doc) \
    {id, type, (flags), (uint16_t)offsetof(hd_fw_config_t, field), (float)(lo), (float)(hi), key, #NAME, unit, \
     (float)(dflt)},
#include "hd_params.def"
};

#undef F32
#undef U32
#undef U16
#undef U8
#undef BOOL
#undef LIVE
#undef REBUILD
#undef RO
#undef CONFIG
#undef CALIB
#undef LO_OPEN
#undef LIB

#define TABLE_ROWS (sizeof TABLE / sizeof TABLE[0])
_Static_assert(TABLE_ROWS == HD_PARAM_ROWS, "HD_PARAM_ROWS counts the table's rows");

static const uint8_t RETIRED[] = {
#define HD_PARAM(...)
#define HD_PARAM_RETIRED(id, key, why) id,
#include "hd_params.def"
};

bool hd_param_is_retired(unsigned id)
{
    for (size_t i = 0; i < sizeof RETIRED; i++) {
        if (RETIRED[i] == id) {
            return true;
        }
    }
    return false;
}

size_t hd_param_count(void)
{
    return TABLE_ROWS;
}

const hd_param_info_t *hd_param_at(size_t i)
{
    return i < TABLE_ROWS ? &TABLE[i] : NULL;
}

const hd_param_info_t *hd_param_by_id(unsigned id)
{
    for (size_t i = 0; i < TABLE_ROWS; i++) {
        if (TABLE[i].id == id) {
            return &TABLE[i];
        }
    }
    return NULL;
}

const hd_param_info_t *hd_param_by_key(const char *key, size_t n)
{
    if (key == NULL) {
        return NULL;
    }
    for (size_t i = 0; i < TABLE_ROWS; i++) {
        if (strlen(TABLE[i].key) == n && memcmp(TABLE[i].key, key, n) == 0) {
            return &TABLE[i];
        }
    }
    return NULL;
}

hd_fw_err_t hd_param_check(const hd_param_info_t *p, float v)
{
    if (p == NULL) {
        return HD_FW_ERR_UNKNOWN_PARAM;
    }
    if (!isfinite(v)) {
        return HD_FW_ERR_NOT_FINITE;
    }
    bool lo_ok = (p->flags & HD_PF_LO_OPEN) ? v > p->lo : v >= p->lo;
    if (!lo_ok || v > p->hi) {
        return HD_FW_ERR_RANGE;
    }
    /* The range keeps v within 2^24, where float32 holds every integer. */
    if (p->type != HD_PT_F32 && v != (float)(int32_t)v) {
        return HD_FW_ERR_NOT_WHOLE;
    }
    return HD_FW_OK;
}

float hd_param_get(const hd_param_info_t *p, const hd_fw_config_t *cfg)
{
    const unsigned char *at = (const unsigned char *)cfg + p->offset;
    switch (p->type) {
    case HD_PT_F32: {
        float v;
        memcpy(&v, at, sizeof v);
        return v;
    }
    case HD_PT_U32: {
        uint32_t v;
        memcpy(&v, at, sizeof v);
        return (float)v;
    }
    case HD_PT_U16: {
        uint16_t v;
        memcpy(&v, at, sizeof v);
        return (float)v;
    }
    default:
        return (float)*at; /* U8, BOOL */
    }
}

hd_fw_err_t hd_param_set(const hd_param_info_t *p, hd_fw_config_t *cfg, float v)
{
    if (p == NULL) {
        return HD_FW_ERR_UNKNOWN_PARAM;
    }
    if (p->flags & HD_PF_RO) {
        return HD_FW_ERR_READ_ONLY;
    }
    hd_fw_err_t rc = hd_param_check(p, v);
    if (rc != HD_FW_OK) {
        return rc;
    }
    unsigned char *at = (unsigned char *)cfg + p->offset;
    switch (p->type) {
    case HD_PT_F32:
        memcpy(at, &v, sizeof v);
        break;
    case HD_PT_U32: {
        uint32_t u = (uint32_t)v;
        memcpy(at, &u, sizeof u);
        break;
    }
    case HD_PT_U16: {
        uint16_t u = (uint16_t)v;
        memcpy(at, &u, sizeof u);
        break;
    }
    default:
        *at = (unsigned char)v;
        break;
    }
    return HD_FW_OK;
}

uint32_t hd_param_table_crc(void)
{
    uint32_t crc = 0u;
    for (size_t i = 0; i < TABLE_ROWS; i++) {
        const hd_param_info_t *p = &TABLE[i];
        uint8_t row[12];
        row[0] = p->id;
        row[1] = p->type;
        row[2] = p->flags;
        row[3] = 0u;
        hd_le_put_f32(row + 4, p->lo);
        hd_le_put_f32(row + 8, p->hi);
        crc = hd_crc32_update(crc, row, sizeof row);
        crc = hd_crc32_update(crc, p->key, strlen(p->key) + 1u);
    }
    return crc;
}
