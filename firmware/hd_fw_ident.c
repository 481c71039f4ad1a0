/* hd_fw_ident: the torque loop's identification run (IDENT_START; issue 23,
 * docs/how-to/tune-torque-loop.md).
 *
 * The background builds the multisine (control/hd_excite) while no run is
 * on and posts the start; the tick adds it to the law's current command,
 * after the law and its limits, and reports both and the feedback torque
 * in an IDENT frame every tick, so that a host breaks the loop at the
 * drive's input.  A run stops by itself after its periods, and at once,
 * said in that tick's frame, when:
 *   the mode that ran is not TORQUE or ZERO_TORQUE, a fallback ran or the
 *     drive is off (the watchdog, every fault reaction): the law's command
 *     goes out alone;
 *   the sum would cross ctrl_current_limit_a: the drive is told the limit,
 *     and the run ends (a clipped excitation is no longer a linear test).
 * The drive never gets more than the limit, whatever the run. */
#include "hd_fw.h"
#include "hd_fw_internal.h"

int hd_fw_ident_prepare(hd_fw_t *fw, const hd_can_cmd_ident_start_t *a, float *peak_a)
{
    hd_fw_ident_t *id = &fw->ident;
    if (!hd_fw_has_drive(fw)) {
        return HD_CAN_RES_UNSUPPORTED;
    }
    if (id->running) {
        return HD_CAN_RES_BUSY;
    }
    if (a->periods < 1u || a->periods > HD_FW_IDENT_PERIODS_MAX ||
        hd_excite_build(&id->excite, a->rms_a) != HD_CTRL_OK) {
        return HD_CAN_RES_OUT_OF_RANGE;
    }
    *peak_a = id->excite.peak_a;
    if (id->excite.peak_a > 0.5f * hd_fw_live(fw)->ctrl.cfg.current_limit_a) {
        return HD_CAN_RES_OUT_OF_RANGE;
    }
    id->ticks_total = ((uint32_t)a->periods + 1u) * HD_EXCITE_PERIOD_TICKS;
    return HD_CAN_RES_OK;
}

void hd_fw_ident_begin(hd_fw_ident_t *id)
{
    id->tick = 0u;
    id->running = true;
}

static bool excitable(const hd_ctrl_output_t *law)
{
    return law->enable && (law->limits & HD_CTRL_LIM_FALLBACK) == 0u &&
           (law->mode == HD_CTRL_TORQUE || law->mode == HD_CTRL_ZERO_TORQUE);
}

float hd_fw_ident_drive(hd_fw_ident_t *id, const hd_ctrl_output_t *law, float current_limit_a)
{
    if (!id->running) {
        return law->current_a;
    }
    uint8_t status = HD_FW_IDENT_RUNNING;
    float drive_a = law->current_a;
    if (!excitable(law)) {
        status = HD_FW_IDENT_MODE;
    } else {
        drive_a += hd_excite_at(&id->excite, id->tick);
        if (drive_a > current_limit_a || drive_a < -current_limit_a) {
            drive_a = drive_a > 0.0f ? current_limit_a : -current_limit_a;
            status = HD_FW_IDENT_LIMIT;
        }
    }
    id->tick++;
    if (status == HD_FW_IDENT_RUNNING && id->tick >= id->ticks_total) {
        status = HD_FW_IDENT_DONE;
    }
    id->running = status == HD_FW_IDENT_RUNNING;
    id->frame = (hd_can_ident_t){law->current_a, drive_a, law->torque_fb_nm,
                                 (uint8_t)(id->tick - 1u), status};
    id->frame_pending = true;
    return drive_a;
}
