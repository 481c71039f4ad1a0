/*
 * hd_params: the parameter table (hd_params.def) as C: ids, lookup by id
 * and by key, range checks, get and set on an hd_fw_config_t.
 *
 * Pure: no I/O, no heap, no globals (the table is const data).
 */
#ifndef HD_PARAMS_H
#define HD_PARAMS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hd_fw_config.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
#define HD_PARAM(id, NAME, ...) HD_PARAM_##NAME = id,
#include "hd_params.def"
    HD_PARAM_ID_MAX_ = 255
} hd_param_id_t;

/* The number of rows (hd_param_count()), as a constant for fixed arrays. */
enum {
#define HD_PARAM(id, NAME, ...) HD_PARAM_ROW_##NAME,
#include "hd_params.def"
    HD_PARAM_ROWS
};

typedef enum { HD_PT_F32, HD_PT_U32, HD_PT_U16, HD_PT_U8, HD_PT_BOOL } hd_param_type_t;

/* Flags (hd_params.def's flags column). */
#define HD_PF_LIVE    0x01u  /* the next tick uses it; the filter keeps its state */
#define HD_PF_REBUILD 0x02u  /* the model is rebuilt: the filter restarts */
#define HD_PF_RO      0x04u  /* read only */
#define HD_PF_CONFIG  0x08u  /* kept in the configuration record */
#define HD_PF_CALIB   0x10u  /* kept in the calibration record */
#define HD_PF_LO_OPEN 0x20u  /* the range excludes lo */

typedef struct {
    uint8_t id;
    uint8_t type;      /* hd_param_type_t */
    uint8_t flags;     /* HD_PF_* */
    uint16_t offset;   /* of the field in hd_fw_config_t */
    float lo;
    float hi;
    const char *key;   /* configuration-text key */
    const char *name;  /* NAME column */
    const char *unit;
    float dflt;        /* hd_fw_config_default's value; NaN: the library's (LIB) */
} hd_param_info_t;

size_t hd_param_count(void);
/* Row i of the table (0 <= i < count), or NULL. */
const hd_param_info_t *hd_param_at(size_t i);
const hd_param_info_t *hd_param_by_id(unsigned id);
/* Is id retired (hd_params.def's HD_PARAM_RETIRED rows)? */
bool hd_param_is_retired(unsigned id);
/* Key of n bytes (need not be NUL-terminated). */
const hd_param_info_t *hd_param_by_key(const char *key, size_t n);

/* Would v be accepted for p?  HD_FW_OK, or HD_FW_ERR_UNKNOWN_PARAM (p
 * NULL), _NOT_FINITE, _RANGE (outside [lo, hi] or (lo, hi]), _NOT_WHOLE.
 * Read-only parameters are checked too; set refuses them. */
hd_fw_err_t hd_param_check(const hd_param_info_t *p, float v);
float hd_param_get(const hd_param_info_t *p, const hd_fw_config_t *cfg);
/* Checks, then writes v into cfg (nothing written on error);
 * HD_FW_ERR_READ_ONLY for read-only rows. */
hd_fw_err_t hd_param_set(const hd_param_info_t *p, hd_fw_config_t *cfg, float v);

/* CRC-32 over every row's id, type, flags, range and key: a host compares
 * it (VERSION item PARAM_TABLE_CRC) with its own copy of the table. */
uint32_t hd_param_table_crc(void);

#ifdef __cplusplus
}
#endif

#endif /* HD_PARAMS_H */
