/* Fuzz: the raw sample stream reader (hal_replay_open, docs/reference/raw-stream.md)
 * feeding the firmware ISR, i.e. arbitrary sensor data from a file.
 * Properties: nothing crashes; a refused file has a message; an accepted
 * one delivers exactly its whole records, then HAL_ERR_END; the ISR takes
 * one step per record and its outputs are finite (invalid samples are
 * flagged). */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <string.h>
#include <unistd.h>

#include "fuzz.h"
#include "hal_mock.h"
#include "hal_replay.h"
#include "hd_fw.h"

static hal_mock_t mock;
static hd_fw_t fw;

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static char path[64];
    if (path[0] == '\0') {
        snprintf(path, sizeof path, "/tmp/hd_fuzz_replay_%ld.hdraw", (long)getpid());
    }
    FILE *f = fopen(path, "wb");
    FUZZ_CHECK(f != NULL);
    FUZZ_CHECK(fwrite(data, 1, size, f) == size);
    fclose(f);
    char err[256];
    err[0] = '\0';
    hal_replay_t *r = hal_replay_open(path, err, sizeof err);
    if (r == NULL) {
        FUZZ_CHECK(err[0] != '\0');
        unlink(path);
        return 0;
    }
    uint64_t records = hal_replay_record_count(r);
    hal_t hal;
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal); /* CAN and NVM */
    hal_replay_bind(r, &hal);   /* sensors and clock */
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    FUZZ_CHECK(hd_fw_init(&fw, &hal, &cfg) == HD_FW_OK);
    uint64_t ticks = 0;
    while (!fw.tick.ended && ticks < 4096u) {
        hd_fw_isr(&fw);
        if (fw.tick.ended) {
            break;
        }
        ticks++;
        FUZZ_CHECK(fw.counters.ticks == ticks);
        const hd_fw_sample_t *s = hd_fw_last_sample(&fw);
        FUZZ_CHECK(isfinite(s->ripple_nm) && isfinite(s->motor_velocity_rad_s));
        FUZZ_CHECK(s->valid ? isfinite(s->torque_filtered_nm) : s->faults != 0u);
    }
    FUZZ_CHECK(ticks == (records < 4096u ? records : 4096u));
    FUZZ_CHECK(hal_replay_position(r) == ticks);
    hal_replay_close(r);
    unlink(path);
    return 0;
}
