#include "host_sim.h"

void host_sim_defaults(const hd_sim_nominal_t *nom, hd_fw_config_t *cfg)
{
    cfg->adc_volts_per_count = (float)nom->adc_v_per_count;
    cfg->motor_cpr = nom->motor_cpr;
    if (nom->output_cpr != 0u) {
        cfg->output_cpr = nom->output_cpr;
    }
    cfg->gear_ratio = (float)nom->gear_ratio;
}
