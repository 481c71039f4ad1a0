/*
 * hal_replay: feeds a recorded raw sample stream (.hdraw, docs/reference/raw-stream.md)
 * from a file through the same ISR.  Host only (files, heap).  The format is
 * read by hd_rawstream's reader; this file only supplies the bytes.
 *
 * Fills the sensors and clock parts of a hal_t.  Each adc_read takes the
 * next record (HAL_ERR_END after the last one); encoder_read returns the
 * same record's encoder part; time_us is record index x ts_us.
 */
#ifndef HAL_REPLAY_H
#define HAL_REPLAY_H

#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct hal_replay hal_replay_t;

/* Opens and checks the header (magic, version 1, record size >= 16,
 * ts_us > 0).  Returns NULL with a message in err on failure.  A trailing
 * partial record is ignored (see hal_replay_trailing_bytes). */
hal_replay_t *hal_replay_open(const char *path, char *err, size_t errlen);
void hal_replay_bind(hal_replay_t *r, hal_t *hal);
uint32_t hal_replay_ts_us(const hal_replay_t *r);
uint64_t hal_replay_record_count(const hal_replay_t *r);
uint64_t hal_replay_position(const hal_replay_t *r); /* records consumed */
uint32_t hal_replay_trailing_bytes(const hal_replay_t *r);
void hal_replay_close(hal_replay_t *r);

#ifdef __cplusplus
}
#endif

#endif /* HAL_REPLAY_H */
