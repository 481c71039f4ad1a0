/* Fuzz: the simulated joint's scenario reader (hd_sim_scenario_parse_n on
 * the raw bytes, not NUL-terminated, and hd_sim_scenario_set), then a few
 * plant samples of any accepted scenario.  Properties: nothing crashes; a
 * rejected input has a "name:line: message"; an input with a NUL byte is
 * rejected; an accepted scenario passes hd_sim_scenario_validate, the plant
 * starts, and its first samples are finite. */
#include <math.h>
#include <string.h>

#include "fuzz.h"
#include "hd_sim_plant.h"
#include "hd_sim_scenario.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1u);
    FUZZ_CHECK(text != NULL);
    memcpy(text, data, size);
    text[size] = '\0';
    static hd_sim_scenario_t sc;
    static hd_sim_plant_t plant;
    char err[256];
    err[0] = '\0';
    hd_sim_scenario_default(&sc);
    int rc = hd_sim_scenario_parse_n(&sc, (const char *)data, size, "fuzz", err, sizeof err);
    if (rc != 0) {
        FUZZ_CHECK(rc == -1 && strncmp(err, "fuzz", 4) == 0);
    } else {
        FUZZ_CHECK(memchr(data, 0, size) == NULL);
        FUZZ_CHECK(hd_sim_scenario_validate(&sc, err, sizeof err) == 0);
        FUZZ_CHECK(hd_sim_plant_init(&plant, &sc, err, sizeof err) == 0);
        for (int i = 0; i < 16; i++) {
            hd_sim_sample_t s;
            if (hd_sim_plant_next(&plant, &s) != 0) {
                break;
            }
            FUZZ_CHECK(isfinite(s.torque_true_nm) && isfinite(s.motor_angle_rad));
        }
    }
    /* the same bytes as one command-line override KEY=VALUE */
    char *eq = strchr(text, '=');
    if (eq != NULL) {
        *eq = '\0';
        hd_sim_scenario_default(&sc);
        err[0] = '\0';
        if (hd_sim_scenario_set(&sc, text, eq + 1, err, sizeof err) != 0) {
            FUZZ_CHECK(err[0] != '\0');
        }
    }
    free(text);
    return 0;
}
