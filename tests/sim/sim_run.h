/* Shared by the simulated-joint tests: one scenario text run through the
 * plant. */
#ifndef SIM_RUN_H
#define SIM_RUN_H

#include <stddef.h>

#include "hd_sim_plant.h"

/* Parses text on top of the scenario defaults, initialises plant with it and
 * runs it into out[0, max).  A parser or plant error fails the calling test
 * with its message.  Returns the number of samples. */
size_t sim_run(hd_sim_plant_t *plant, const char *text, hd_sim_sample_t *out, size_t max);

#endif
