/* Fuzz: the firmware configuration text parser (hd_config_text_parse) and
 * its number parser.
 * Properties: nothing crashes or reads past `len` (the input is not NUL
 * terminated); on success the configuration passes hd_fw_config_check; on
 * error it is byte-identical to before and the error has a message and a
 * documented code; a parsed number is finite. */
#include <math.h>
#include <string.h>

#include "fuzz.h"
#include "hd_config_text.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static hd_fw_config_t cfg, before;
    hd_fw_config_default(&cfg);
    memcpy(&before, &cfg, sizeof cfg);
    hd_cfgtxt_error_t err;
    memset(&err, 0, sizeof err);
    int rc = hd_config_text_parse((const char *)data, size, &cfg, &err);
    if (rc == HD_FW_OK) {
        FUZZ_CHECK(hd_fw_config_check(&cfg, NULL) == HD_FW_OK);
    } else {
        FUZZ_CHECK(rc < 0 && strcmp(hd_fw_err_str(rc), "unknown error") != 0);
        FUZZ_CHECK(err.code == rc);
        FUZZ_CHECK(err.message != NULL && err.message[0] != '\0');
        FUZZ_CHECK(memcmp(&cfg, &before, sizeof cfg) == 0);
    }
    float v = 0.0f;
    if (hd_config_parse_float((const char *)data, size < 64u ? size : 64u, &v) == 0) {
        FUZZ_CHECK(isfinite(v));
    }
    return 0;
}
