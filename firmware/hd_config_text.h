/*
 * hd_config_text: the firmware configuration text file (docs/design/firmware.md).
 *
 *   # comment
 *   gear_ratio = 100
 *   r_nm2 = 1
 *   offset = on
 *   block = motor 2 1000       # kind order_or_hz q_nm2 [off]
 *   block = output 1 1000
 *
 * One `key = value` per line ('=' optional), '#' starts a comment.  The
 * keys are the rows of hd_params.def (key column; read-only ones are
 * refused) plus `block`.  The first `block` line drops the blocks inherited
 * from the base configuration; each further one appends.  Values: numbers
 * in decimal (integer parameters take whole numbers without a leading zero,
 * so `01024` is an error, not octal), on/off/1/0/yes/no for flags; each is
 * checked against its table range.  A key given twice is an error naming
 * both lines.  The text must be printable: a NUL or other control byte
 * (except tab and CR) is an error with its line; bytes >= 0x80 are allowed
 * only in comments, as well-formed UTF-8.  At most HD_CFGTXT_MAX_BYTES bytes.  Parsing is all or
 * nothing: on any error the configuration is unchanged and the error names
 * the line.
 *
 * Pure C: parses from a caller-provided buffer, no heap, no stdio, no libm
 * (a small decimal parser replaces strtod, which allocates in newlib).
 */
#ifndef HD_CONFIG_TEXT_H
#define HD_CONFIG_TEXT_H

#include <stddef.h>

#include "hd_fw.h"
#include "hd_params.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int code;             /* hd_fw_err_t (HD_FW_OK on success) */
    unsigned line;        /* 1-based line of the error; 0 for whole-file errors
                             (the model as a whole refused: HD_FW_ERR_KF, ...) */
    const char *message;  /* static string */
    unsigned first_line;  /* HD_FW_ERR_DUPLICATE: the key's first line */
    unsigned param_id;    /* HD_FW_ERR_RANGE: the parameter, when known */
} hd_cfgtxt_error_t;

#define HD_CFGTXT_MAX_LINE 200u
#define HD_CFGTXT_MAX_BYTES 16384u

/* Applies the text (len bytes, need not be NUL-terminated) on top of *cfg.
 * Returns HD_FW_OK, or an hd_fw_err_t with *cfg unchanged; err may be NULL. */
int hd_config_text_parse(const char *text, size_t len, hd_fw_config_t *cfg,
                         hd_cfgtxt_error_t *err);

/* The keys a text gave: line_of[i] is the line of parameter row i
 * (hd_param_at(i)), 0 if the text does not set it; blocks: it has a block line
 * (so the blocks of the result replace the base's). */
typedef struct {
    bool blocks;
    unsigned line_of[HD_PARAM_ROWS];
} hd_cfgtxt_keys_t;

/* hd_config_text_parse, and on success what the text gave in *keys (may be
 * NULL): a host turns exactly those into commands (tools/hdtools/cfgtext.py
 * calls it through ctypes, so the tools parse as the firmware does). */
int hd_config_text_parse_keys(const char *text, size_t len, hd_fw_config_t *cfg,
                              hd_cfgtxt_error_t *err, hd_cfgtxt_keys_t *keys);
/* sizeof(hd_fw_config_t), for a host that allocates one through ctypes. */
size_t hd_config_text_config_size(void);
/* Block i of cfg as a `block` line gives it: lock (hd_kf_lock_t), order or
 * frequency, q, enabled.  -1 if there is no block i. */
int hd_config_text_block(const hd_fw_config_t *cfg, unsigned i, unsigned *lock, float *order,
                         float *q_nm2, unsigned *enabled);

/* Decimal number parser used above (exposed for tests): the whole of
 * [s, s+n) must be one number such as "-1.5e-3".  Returns 0 or -1. */
int hd_config_parse_float(const char *s, size_t n, float *out);

#ifdef __cplusplus
}
#endif

#endif /* HD_CONFIG_TEXT_H */
