/* host_nvm: hdjoint-host's NVM image file (--nvm) and what it stores in
 * NVM before the firmware boots (--calib, --profile).  Host only. */
#ifndef HOST_NVM_H
#define HOST_NVM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal.h"
#include "hal_mock.h"

typedef struct {
    const char *path;      /* NULL: no image file */
    uint8_t saved[HAL_MOCK_NVM_BYTES];
    bool missing;          /* no file yet: written at the start */
    uint32_t writes;
} nvm_file_t;

/* Loads n->path into nvm (HAL_MOCK_NVM_BYTES).  A missing file is an erased
 * device, written at the first host_nvm_sync; anything else must be a whole
 * image.  -1 with a message in err. */
int host_nvm_load(nvm_file_t *n, uint8_t *nvm, char *err, size_t err_len);
/* Writes the image (temporary file, fsync, rename) if it changed since the
 * last write or load.  -1 with a message in err. */
int host_nvm_sync(nvm_file_t *n, const uint8_t *nvm, char *err, size_t err_len);

/* Stores a calibration record with this gain and offset; -1 on failure. */
int host_provision_calibration(hal_t *hal, float gain, float offset);
/* Stores the profile record of a record file (hdsense profile record) as
 * is: the firmware checks at boot that it is for this joint.  -1 with a
 * message in err. */
int host_provision_profile(hal_t *hal, const char *path, char *err, size_t err_len);

#endif
