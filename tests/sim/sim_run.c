#include "sim_run.h"

#include "hd_sim_scenario.h"
#include "unity.h"

size_t sim_run(hd_sim_plant_t *plant, const char *text, hd_sim_sample_t *out, size_t max)
{
    static char err[512];
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    if (hd_sim_scenario_parse(&sc, text, "test", err, sizeof(err)) != 0) {
        TEST_FAIL_MESSAGE(err);
    }
    if (hd_sim_plant_init(plant, &sc, err, sizeof(err)) != 0) {
        TEST_FAIL_MESSAGE(err);
    }
    size_t n = 0;
    while (n < max && hd_sim_plant_next(plant, &out[n]) == 0) {
        n++;
    }
    return n;
}
