/* Configuration text parser: good files, malformed files (error + line,
 * configuration unchanged), number parsing against strtod. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hd_config_text.h"
#include "hd_params.h"
#include "unity.h"

static hd_fw_config_t base;

void setUp(void)
{
    hd_fw_config_default(&base);
}
void tearDown(void) {}

static int parse(const char *text, hd_fw_config_t *cfg, hd_cfgtxt_error_t *err)
{
    return hd_config_text_parse(text, strlen(text), cfg, err);
}

static void test_good_file_sets_every_key(void)
{
    const char *text =
        "# the paper's model\n"
        "gear_ratio = 80\n"
        "r_nm2=0.5\n"
        "p0_nm2 = 100   # trailing comment\n"
        "\n"
        "offset = on\n"
        "offset_q_nm2 = 1e-6\n"
        "output_p0_nm2 = 0.02\n"
        "offset_jump_nm = 0.75\n"
        "q_motion_ref_rad = 0.1\n"
        "block = motor 2 1000\n"
        "block = output 1 1e3\n"
        "block = fixed 50 0.25 off\n"
        "inertia_kgm2 = 0.01\n"
        "viscous_nm_s_rad 0.2\n"
        "coulomb_nm = 1.5\n"
        "track_bandwidth_hz = 30\n"
        "telemetry_rate_hz = 250\n"
        "node_id = 12\n"
        "filter = off\n"
        "motor_cpr = 8192\r\n";
    hd_fw_config_t cfg = base;
    hd_cfgtxt_error_t err;
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, parse(text, &cfg, &err));
    TEST_ASSERT_EQUAL_FLOAT(80.0f, cfg.gear_ratio);
    TEST_ASSERT_EQUAL_FLOAT(0.5f, cfg.kf.r_nm2);
    TEST_ASSERT_EQUAL_FLOAT(100.0f, cfg.kf.p0_nm2);
    TEST_ASSERT_EQUAL_UINT8(1, cfg.kf.offset_enabled);
    TEST_ASSERT_EQUAL_FLOAT(1e-6f, cfg.kf.offset_q_nm2);
    TEST_ASSERT_EQUAL_FLOAT(0.02f, cfg.kf.output_p0_nm2);
    TEST_ASSERT_EQUAL_FLOAT(0.75f, cfg.kf.offset_jump_nm);
    TEST_ASSERT_EQUAL_FLOAT(0.1f, cfg.kf.q_motion_ref_rad);
    TEST_ASSERT_EQUAL_UINT8(3, cfg.kf.block_count); /* the defaults' blocks were replaced */
    TEST_ASSERT_EQUAL_UINT8(HD_KF_LOCK_MOTOR, cfg.kf.blocks[0].lock);
    TEST_ASSERT_EQUAL_FLOAT(2.0f, cfg.kf.blocks[0].order);
    TEST_ASSERT_EQUAL_FLOAT(1000.0f, cfg.kf.blocks[0].q_nm2);
    TEST_ASSERT_EQUAL_UINT8(HD_KF_LOCK_OUTPUT, cfg.kf.blocks[1].lock);
    TEST_ASSERT_EQUAL_UINT8(HD_KF_LOCK_FIXED, cfg.kf.blocks[2].lock);
    TEST_ASSERT_EQUAL_FLOAT(50.0f, cfg.kf.blocks[2].order);
    TEST_ASSERT_EQUAL_UINT8(0, cfg.kf.blocks[2].enabled);
    TEST_ASSERT_EQUAL_FLOAT(0.01f, cfg.expected.inertia_kgm2);
    TEST_ASSERT_EQUAL_FLOAT(0.2f, cfg.expected.viscous_nm_s_rad);
    TEST_ASSERT_EQUAL_FLOAT(1.5f, cfg.expected.coulomb_nm);
    TEST_ASSERT_EQUAL_FLOAT(30.0f, cfg.track_bandwidth_hz);
    TEST_ASSERT_EQUAL_UINT16(250, cfg.telemetry_rate_hz);
    TEST_ASSERT_EQUAL_UINT8(12, cfg.node_id);
    TEST_ASSERT_EQUAL_UINT8(0, cfg.filter_enabled);
    TEST_ASSERT_EQUAL_UINT32(8192, cfg.motor_cpr);
}

static void test_empty_file_keeps_the_base(void)
{
    hd_fw_config_t cfg = base;
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, parse("# nothing\n\n   \n", &cfg, NULL));
    TEST_ASSERT_EQUAL_MEMORY(&base, &cfg, sizeof cfg);
}

typedef struct {
    const char *text;
    int code;
    unsigned line;
} bad_case_t;

static void test_malformed_files_report_the_line_and_change_nothing(void)
{
    const bad_case_t cases[] = {
        {"gear_ratio = 50\nbogus = 1\n", HD_FW_ERR_UNKNOWN_PARAM, 2},
        {"r_nm2 = 1.2.3\n", HD_FW_ERR_SYNTAX, 1},
        {"r_nm2 =\n", HD_FW_ERR_SYNTAX, 1},
        {"r_nm2 = 1 2\n", HD_FW_ERR_SYNTAX, 1},
        {"\n\nr_nm2 = -1\n", HD_FW_ERR_RANGE, 3},
        {"r_nm2 = 0\n", HD_FW_ERR_RANGE, 1},
        {"r_nm2 = nan\n", HD_FW_ERR_SYNTAX, 1},
        {"r_nm2 = 1e999\n", HD_FW_ERR_SYNTAX, 1},
        {"node_id = 200\n", HD_FW_ERR_RANGE, 1},
        {"node_id = 0\n", HD_FW_ERR_RANGE, 1},
        {"node_id = -3\n", HD_FW_ERR_SYNTAX, 1},
        {"telemetry_rate_hz = 2000\n", HD_FW_ERR_RANGE, 1},
        {"offset = maybe\n", HD_FW_ERR_SYNTAX, 1},
        {"block = motor 2\n", HD_FW_ERR_SYNTAX, 1},
        {"block = wobble 2 1\n", HD_FW_ERR_SYNTAX, 1},
        {"block = fixed 600 1\n", HD_FW_ERR_RANGE, 1},
        {"block = motor 0 1\n", HD_FW_ERR_RANGE, 1},
        {"block = motor 2 -1\n", HD_FW_ERR_RANGE, 1},
        {"block = motor 1 1\nblock = motor 2 1\nblock = motor 3 1\nblock = motor 4 1\n"
         "block = motor 5 1\nblock = motor 6 1\nblock = motor 7 1\nblock = motor 8 1\n"
         "block = motor 9 1\n",
         HD_FW_ERR_TOO_MANY_BLOCKS, 9},
        /* outside a table range: the line says so */
        {"gear_ratio = 0.5\n", HD_FW_ERR_RANGE, 1},
        {"track_bandwidth_hz = 200\n", HD_FW_ERR_RANGE, 1},
        {"\nnyquist_fraction = 1.5\n", HD_FW_ERR_RANGE, 2},
        {"telemetry_rate_hz = 2.5\n", HD_FW_ERR_SYNTAX, 1},
        /* each line fine, the whole refused (p0 / R beyond float32) */
        {"r_nm2 = 1e-6\np0_nm2 = 100\n", HD_FW_ERR_KF, 0},
        /* physically absurd: a line 121x its zero-load size at the torque
         * limit; a current model with eta x eta_b > 1; a negative envelope */
        {"ripple_load_coeff_per_nm = 0.6\n", HD_FW_ERR_KF, 0},
        {"ripple_load_coeff_per_nm = 0.2\ntorque_limit_nm = 1000\n", HD_FW_ERR_KF, 0},
        {"current_nm_per_a = 10\ncurrent_backdrive_nm_per_a = 9\n", HD_FW_ERR_EXPECTED, 0},
        {"correction_max_nm = -1\n", HD_FW_ERR_RANGE, 1},
        /* decimal only: a leading zero is not octal, it is an error */
        {"motor_cpr = 01024\n", HD_FW_ERR_SYNTAX, 1},
        {"node_id = 0x10\n", HD_FW_ERR_SYNTAX, 1},
        /* a key twice: the second line, naming the first */
        {"gear_ratio = 80\nr_nm2 = 1\ngear_ratio = 90\n", HD_FW_ERR_DUPLICATE, 3},
        {"block_count = 3\n", HD_FW_ERR_READ_ONLY, 1},
        {"gear_ratio = 80\x01\n", HD_FW_ERR_BYTES, 1},
        {"# ok: \xc3\xa9 in a comment\ngear_ratio = 8\xc3\xa9" "0\n", HD_FW_ERR_BYTES, 2},
        /* comments are UTF-8 text: a Latin-1 byte, a cut sequence, an overlong form */
        {"# caf\xe9\n", HD_FW_ERR_BYTES, 1},
        {"gear_ratio = 80\n# \xe2\x82\n", HD_FW_ERR_BYTES, 2},
        {"# \xc0\xaf\n", HD_FW_ERR_BYTES, 1},
    };
    for (unsigned i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        hd_fw_config_t cfg = base;
        hd_cfgtxt_error_t err;
        int rc = parse(cases[i].text, &cfg, &err);
        TEST_ASSERT_EQUAL_INT_MESSAGE(cases[i].code, rc, cases[i].text);
        TEST_ASSERT_EQUAL_INT_MESSAGE(cases[i].code, err.code, cases[i].text);
        TEST_ASSERT_EQUAL_UINT_MESSAGE(cases[i].line, err.line, cases[i].text);
        TEST_ASSERT_NOT_NULL(err.message);
        TEST_ASSERT_EQUAL_MEMORY_MESSAGE(&base, &cfg, sizeof cfg, cases[i].text);
    }
}

static void test_duplicate_names_both_lines(void)
{
    hd_fw_config_t cfg = base;
    hd_cfgtxt_error_t err;
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_DUPLICATE,
                          parse("node_id = 3\n\n# x\nnode_id = 4\n", &cfg, &err));
    TEST_ASSERT_EQUAL_UINT(4, err.line);
    TEST_ASSERT_EQUAL_UINT(1, err.first_line);
}

static void test_nul_byte_stops_nothing_silently(void)
{
    /* Text after a NUL used to be ignored (node_id = 999 included). */
    static const char text[] = "gear_ratio = 80\n\0node_id = 999\n";
    hd_fw_config_t cfg = base;
    hd_cfgtxt_error_t err;
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_BYTES, hd_config_text_parse(text, sizeof text - 1, &cfg, &err));
    TEST_ASSERT_EQUAL_UINT(2, err.line);
    TEST_ASSERT_EQUAL_MEMORY(&base, &cfg, sizeof cfg);
}

static void test_size_limit(void)
{
    static char text[HD_CFGTXT_MAX_BYTES + 2];
    memset(text, '\n', sizeof text);
    hd_fw_config_t cfg = base;
    hd_cfgtxt_error_t err;
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_config_text_parse(text, HD_CFGTXT_MAX_BYTES, &cfg, &err));
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_TOO_LONG,
                          hd_config_text_parse(text, HD_CFGTXT_MAX_BYTES + 1u, &cfg, &err));
    /* the message states the limit in force (it is typed in the text) */
    char limit[32];
    snprintf(limit, sizeof limit, " %u bytes", (unsigned)HD_CFGTXT_MAX_BYTES);
    TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err.message, limit), err.message);
}

/* Every writable row of hd_params.def is a key: set it to its upper bound
 * (or on) in a file and read it back through the table. */
static void test_every_table_row_is_a_key(void)
{
    unsigned n = 0;
    for (size_t i = 0; i < hd_param_count(); i++) {
        const hd_param_info_t *p = hd_param_at(i);
        if (p->flags & HD_PF_RO) {
            continue;
        }
        char text[128];
        float want = p->hi;
        if (p->type == HD_PT_BOOL) {
            snprintf(text, sizeof text, "%s = on\n", p->key);
        } else if (p->type == HD_PT_F32) {
            snprintf(text, sizeof text, "%s = %.9g\n", p->key, (double)want);
        } else {
            snprintf(text, sizeof text, "%s = %lu\n", p->key, (unsigned long)want);
        }
        hd_fw_config_t cfg = base;
        hd_cfgtxt_error_t err;
        int rc = parse(text, &cfg, &err);
        if (rc == HD_FW_ERR_KF || rc == HD_FW_ERR_CONTROL) {
            continue; /* the bound alone is a refused model (e.g. p0 / R; the position
                         window's minimum above its maximum) */
        }
        TEST_ASSERT_EQUAL_INT_MESSAGE(HD_FW_OK, rc, text);
        TEST_ASSERT_EQUAL_FLOAT_MESSAGE(want, hd_param_get(p, &cfg), text);
        n++;
    }
    TEST_ASSERT_TRUE(n >= 20u);
}

static void test_long_line_and_null_are_rejected(void)
{
    char text[400];
    memset(text, 'x', sizeof text);
    text[sizeof text - 1] = '\n';
    hd_fw_config_t cfg = base;
    hd_cfgtxt_error_t err;
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_SYNTAX, hd_config_text_parse(text, sizeof text, &cfg, &err));
    TEST_ASSERT_EQUAL_UINT(1, err.line);
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_NULL, hd_config_text_parse("x", 1, NULL, &err));
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_NULL, hd_config_text_parse(NULL, 3, &cfg, &err));
}

static void test_number_parser_agrees_with_strtod(void)
{
    const char *good[] = {"0", "1", "-1", "+2.5", "1000", "1e3", "1E3", "-2.5e-3", ".5", "5.",
                          "0.1", "3.14159265358979", "6.60", "1e-30", "3.4e38", "123456789012345678901234",
                          "0.000000000000000000000123", "-0"};
    for (unsigned i = 0; i < sizeof good / sizeof good[0]; i++) {
        float v = -99.0f;
        TEST_ASSERT_EQUAL_INT_MESSAGE(0, hd_config_parse_float(good[i], strlen(good[i]), &v), good[i]);
        double ref = strtod(good[i], NULL); /* independent reference */
        double tol = 1e-6 * (ref < 0 ? -ref : ref) + 1e-45;
        TEST_ASSERT_DOUBLE_WITHIN_MESSAGE(tol, ref, (double)v, good[i]);
    }
    const char *bad[] = {"", "-", ".", "e3", "1e", "1e+", "abc", "1.0x", "1..0", "nan", "inf",
                         "0x10", "1e39", "1e-60", " 1"};
    for (unsigned i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        float v;
        TEST_ASSERT_EQUAL_INT_MESSAGE(-1, hd_config_parse_float(bad[i], strlen(bad[i]), &v), bad[i]);
    }
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_good_file_sets_every_key);
    RUN_TEST(test_empty_file_keeps_the_base);
    RUN_TEST(test_malformed_files_report_the_line_and_change_nothing);
    RUN_TEST(test_duplicate_names_both_lines);
    RUN_TEST(test_nul_byte_stops_nothing_silently);
    RUN_TEST(test_size_limit);
    RUN_TEST(test_every_table_row_is_a_key);
    RUN_TEST(test_long_line_and_null_are_rejected);
    RUN_TEST(test_number_parser_agrees_with_strtod);
    return UNITY_END();
}
