/* host_options: hdjoint-host's command line (getopt_long) and the
 * cansend-style frames of --cmd / --cmd-at.  Host only. */
#ifndef HOST_OPTIONS_H
#define HOST_OPTIONS_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"

typedef struct {
    const char *sensors;
    const char *can;
    const char *config;
    const char *csv;
    const char *nvm_file;
    bool realtime;
    double duration_s;
    bool have_calib;
    float calib_gain;
    float calib_offset;
    const char **cmds;   /* argc entries at most */
    uint64_t *cmd_due;   /* tick from which each may be delivered (--cmd-at) */
    int n_cmds;
    bool quiet;
    const char *profile; /* profile record file to store in NVM before start */
} host_options_t;

/* Fills o from the command line.  Returns 0 to run, 1 after --help or
 * --version (printed), -1 after a one-line error on stderr.  o->cmds and
 * o->cmd_due are heap blocks that live until exit. */
int host_parse_args(int argc, char **argv, host_options_t *o);

/* "123#0011AA" (cansend: 3 id digits for 11 bits, 8 for 29 bits, up to 8
 * data bytes) -> a classic frame; -1 if it is not one. */
int host_parse_frame(const char *s, hal_can_frame_t *f);

#endif
