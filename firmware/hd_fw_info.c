/* hd_fw_info: what VERSION and INFO answer (hd_protocol.def, HD_INFO_ITEM):
 * versions of the firmware, protocol and records, the board, the boot
 * record and the counters.  Read-only. */
#include "hd_fw_internal.h"
#include "hd_fw_records.h"
#include "hd_params.h"

#ifndef HD_FW_VERSION_MAJOR
#define HD_FW_VERSION_MAJOR 0
#define HD_FW_VERSION_MINOR 0
#define HD_FW_VERSION_PATCH 0
#endif
#ifndef HD_FW_GIT_HASH
#define HD_FW_GIT_HASH 0u
#endif

static uint32_t version_word(void)
{
    return (uint32_t)HD_FW_VERSION_MAJOR * 65536u + (uint32_t)HD_FW_VERSION_MINOR * 256u +
           (uint32_t)HD_FW_VERSION_PATCH;
}

/* The CAN backend's own counters (what it saw below the firmware: frames
 * the controller lost or aborted, error frames, bus-off, error counters); zero without a counters
 * function.  Read in the background: a counter may be one tick old. */
static hal_counters_t can_counters(const hd_fw_t *fw)
{
    hal_counters_t c = {0};
    if (fw->hal->can.counters != NULL) {
        fw->hal->can.counters(fw->hal->can.ctx, &c);
    }
    return c;
}

bool hd_fw_info_item(const hd_fw_t *fw, uint8_t item, uint32_t *v)
{
    const hd_fw_counters_t *c = &fw->counters;
    const hal_boot_info_t *b = &fw->bg.boot;
    switch (item) {
    case HD_INFO_PROTOCOL_VERSION: *v = HD_CAN_PROTOCOL_VERSION; return true;
    case HD_INFO_FIRMWARE_VERSION: *v = version_word(); return true;
    case HD_INFO_GIT_HASH: *v = (uint32_t)HD_FW_GIT_HASH; return true;
    case HD_INFO_BOARD_ID: *v = fw->hal->system.board_id; return true;
    case HD_INFO_CALIB_RECORD_VERSION: *v = HD_CALIB_RECORD_VERSION; return true;
    case HD_INFO_CONFIG_RECORD_VERSION: *v = HD_CONFIG_RECORD_VERSION; return true;
    case HD_INFO_PROFILE_RECORD_VERSION: *v = HD_PROFILE_RECORD_VERSION; return true;
    case HD_INFO_PARAM_TABLE_CRC: *v = hd_param_table_crc(); return true;
    case HD_INFO_RESET_CAUSE: *v = b->reset_cause; return true;
    case HD_INFO_FAULT_PC: *v = b->fault_valid ? b->fault_pc : 0u; return true;
    case HD_INFO_FAULT_LR: *v = b->fault_valid ? b->fault_lr : 0u; return true;
    case HD_INFO_FAULT_CFSR: *v = b->fault_valid ? b->fault_cfsr : 0u; return true;
    case HD_INFO_FAULT_HFSR: *v = b->fault_valid ? b->fault_hfsr : 0u; return true;
    case HD_INFO_FAULT_ADDR: *v = b->fault_valid ? b->fault_addr : 0u; return true;
    case HD_INFO_BOARD_INIT_ERRORS: *v = b->init_errors; return true;
    case HD_INFO_TICKS: *v = c->ticks; return true;
    case HD_INFO_VALID_SAMPLES: *v = c->valid_samples; return true;
    case HD_INFO_FAULT_TICKS: *v = c->fault_ticks; return true;
    case HD_INFO_DEADLINE_MISSES: *v = c->deadline_misses; return true;
    case HD_INFO_TELEMETRY_FRAMES: *v = c->telemetry_frames; return true;
    case HD_INFO_COMMANDS: *v = c->commands; return true;
    case HD_INFO_COMMAND_ERRORS: *v = c->command_errors; return true;
    case HD_INFO_COMMAND_QUEUE_FULL: *v = c->command_queue_full; return true;
    case HD_INFO_FRAMES_DROPPED: *v = c->frames_dropped; return true;
    case HD_INFO_FOREIGN_FRAMES: *v = c->foreign_frames; return true;
    case HD_INFO_FEEDFORWARD_FRAMES: *v = c->feedforward_frames; return true;
    case HD_INFO_CAN_RX_OVERRUNS: *v = can_counters(fw).can_rx_overruns; return true;
    case HD_INFO_CAN_ERROR_FRAMES: *v = can_counters(fw).can_error_frames; return true;
    case HD_INFO_CAN_BUS_OFF: *v = can_counters(fw).can_bus_off; return true;
    case HD_INFO_CAN_TX_ABORTED: *v = can_counters(fw).can_tx_aborted; return true;
    case HD_INFO_CAN_TX_ERROR_COUNT: *v = can_counters(fw).can_tx_error_count; return true;
    case HD_INFO_CAN_RX_ERROR_COUNT: *v = can_counters(fw).can_rx_error_count; return true;
    case HD_INFO_UNMODELLED_STEPS: *v = c->unmodelled_steps; return true;
    case HD_INFO_CORRECTION_LIMITED: *v = c->correction_limited; return true;
    default: return false;
    }
}
