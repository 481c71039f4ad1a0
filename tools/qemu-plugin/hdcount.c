/*
 * hdcount: a QEMU TCG plugin that counts guest instructions between marker
 * addresses, deterministically (QEMU emulates no cycle counter).
 *
 *   qemu-system-arm ... -plugin hdcount.so,begin=0xADDR,end=0xADDR[,section=0xADDR],out=FILE
 *
 * begin/end/section are the addresses of the image's marker functions
 * (hd_mark_begin, hd_mark_end, hd_mark_section; arm-none-eabi-nm).  When the
 * guest executes the first instruction of `begin`, counting starts; the
 * first instruction of `end` stops it and closes one interval.  The
 * interval holds every instruction executed in between: the rest of the
 * begin marker (its `bx lr`), the measured code and everything it calls,
 * and the call to `end`.  The fixed overhead is measured by an empty
 * interval and subtracted by the caller (tools/target).
 *
 * Output (text, one record per line):
 *   I <n>           one interval: n instructions
 *   P <pc> <n>      per-address execution counts inside intervals, written
 *                   when a section closes (`section` executed, or exit); pc hex
 *   S               end of a section
 *   T <n>           at exit: all instructions the guest executed
 *
 * Build: cc -shared -fPIC -O2 -o hdcount.so hdcount.c   (no QEMU headers
 * needed: hd_qemu_plugin_abi.h declares the API).
 */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hd_qemu_plugin_abi.h"

HD_QEMU_PLUGIN_EXPORT int qemu_plugin_version = HD_QEMU_PLUGIN_API_VERSION;

/* Per-address histogram for code below HIST_LIMIT (the image's flash);
 * Thumb instructions are 2-byte aligned. */
#define HIST_LIMIT 0x00400000u
#define HIST_SLOTS (HIST_LIMIT / 2u)

static uint64_t g_begin = UINT64_MAX;
static uint64_t g_end = UINT64_MAX;
static uint64_t g_section = UINT64_MAX;
static FILE *g_out;
static int g_counting;
static uint64_t g_interval;
static uint64_t g_total;
static uint64_t *g_hist;
static int g_hist_dirty;

static void flush_section(void)
{
    if (g_hist_dirty) {
        for (uint32_t i = 0; i < HIST_SLOTS; i++) {
            if (g_hist[i] != 0u) {
                fprintf(g_out, "P %" PRIx32 " %" PRIu64 "\n", i * 2u, g_hist[i]);
                g_hist[i] = 0u;
            }
        }
        g_hist_dirty = 0;
    }
    fputs("S\n", g_out);
}

static void on_insn(unsigned int vcpu_index, void *userdata)
{
    (void)vcpu_index;
    uint64_t pc = (uint64_t)(uintptr_t)userdata;
    g_total++;
    if (pc == g_begin) {
        g_counting = 1;
        g_interval = 0;
        return;
    }
    if (pc == g_end) {
        if (g_counting) {
            fprintf(g_out, "I %" PRIu64 "\n", g_interval);
        }
        g_counting = 0;
        return;
    }
    if (pc == g_section) {
        flush_section();
        return;
    }
    if (g_counting) {
        g_interval++;
        if (pc < HIST_LIMIT) {
            g_hist[pc / 2u]++;
            g_hist_dirty = 1;
        }
    }
}

static void on_tb_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    (void)id;
    size_t n = qemu_plugin_tb_n_insns(tb);
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint64_t pc = qemu_plugin_insn_vaddr(insn);
        qemu_plugin_register_vcpu_insn_exec_cb(insn, on_insn, QEMU_PLUGIN_CB_NO_REGS,
                                               (void *)(uintptr_t)pc);
    }
}

static void on_qemu_exit(qemu_plugin_id_t id, void *userdata)
{
    (void)id;
    (void)userdata;
    if (g_hist_dirty) {
        flush_section();
    }
    fprintf(g_out, "T %" PRIu64 "\n", g_total);
    fclose(g_out);
    free(g_hist);
}

static int parse_addr(const char *text, uint64_t *out)
{
    char *end = NULL;
    unsigned long long v = strtoull(text, &end, 0);
    if (end == text || *end != '\0') {
        return -1;
    }
    *out = (uint64_t)v & ~(uint64_t)1u; /* drop the Thumb bit of a symbol value */
    return 0;
}

HD_QEMU_PLUGIN_EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info,
                                              int argc, char **argv)
{
    (void)info;
    const char *out_path = NULL;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        int bad = 0;
        if (strncmp(a, "begin=", 6) == 0) {
            bad = parse_addr(a + 6, &g_begin);
        } else if (strncmp(a, "end=", 4) == 0) {
            bad = parse_addr(a + 4, &g_end);
        } else if (strncmp(a, "section=", 8) == 0) {
            bad = parse_addr(a + 8, &g_section);
        } else if (strncmp(a, "out=", 4) == 0) {
            out_path = a + 4;
        } else {
            bad = 1;
        }
        if (bad) {
            fprintf(stderr, "hdcount: bad argument '%s' (begin=ADDR,end=ADDR,section=ADDR,out=FILE)\n", a);
            return -1;
        }
    }
    if (g_begin == UINT64_MAX || g_end == UINT64_MAX || out_path == NULL) {
        fprintf(stderr, "hdcount: begin=, end= and out= are required\n");
        return -1;
    }
    g_out = fopen(out_path, "w");
    g_hist = calloc(HIST_SLOTS, sizeof *g_hist);
    if (g_out == NULL || g_hist == NULL) {
        fprintf(stderr, "hdcount: cannot open %s or allocate the histogram\n", out_path);
        return -1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_tb_trans);
    qemu_plugin_register_atexit_cb(id, on_qemu_exit, NULL);
    return 0;
}
