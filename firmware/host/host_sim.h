/* host_sim: what the host programs take from the simulated joint's
 * nominal constants (hdjoint-host --sensors sim:, hd_emu).  Host only. */
#ifndef HOST_SIM_H
#define HOST_SIM_H

#include "hd_fw_config.h"
#include "hd_sim_plant.h"

/* The sensor's and encoders' constants as firmware defaults (what a board's
 * factory configuration, the joint's data sheet, would hold).  No oracle
 * (issue 12): the expected-torque model (J, b, Fc) is NOT the plant's; it
 * stays as *cfg has it (the firmware defaults or a configuration file). */
void host_sim_defaults(const hd_sim_nominal_t *nom, hd_fw_config_t *cfg);

#endif
