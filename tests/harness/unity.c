/* Implementation of the project's Unity-compatible harness; see unity.h. */
#include "unity.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

jmp_buf UnityAbortFrame;

static struct {
    const char *file;
    const char *test_name;
    int test_line;
    unsigned tests;
    unsigned failures;
    unsigned ignored;
    int current_failed;
    int current_ignored;
} unity;

/* Kept apart from `unity`: UnityBegin clears that, and the options are parsed
 * before it. */
static struct {
    const char *include; /* comma-separated name parts, NULL: every test */
    const char *exclude;
    int list_only;
    unsigned selected;
} options;

static void print_usage(const char *program)
{
    printf("Options: %s [-n NAME] [-x NAME] [-l] [-h]\n"
           "  -n NAME  run only tests whose name contains NAME (-f, -n=NAME;"
           " a comma-separated list)\n"
           "  -x NAME  skip tests whose name contains NAME\n"
           "  -l       list the test names\n"
           "  -h       this text\n", program);
}

int UnityParseOptions(int argc, char **argv)
{
    memset(&options, 0, sizeof options);
    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        if (arg[0] != '-' || arg[1] == '\0') {
            printf("ERROR: Unknown Argument %s\n", arg);
            print_usage(argv[0]);
            return 1;
        }
        const char **target = NULL;
        switch (arg[1]) {
        case 'n':
        case 'f':
            target = &options.include;
            break;
        case 'x':
            target = &options.exclude;
            break;
        case 'l':
            options.list_only = 1;
            continue;
        case 'q':
        case 'v':
            continue; /* Unity's verbosity flags: one output format here */
        case 'h':
            print_usage(argv[0]);
            return 1;
        default:
            printf("ERROR: Unknown Option %s\n", arg);
            print_usage(argv[0]);
            return 1;
        }
        if (arg[2] == '=') {
            *target = arg + 3;
        } else if (arg[2] != '\0') {
            *target = arg + 2;
        } else if (i + 1 < argc) {
            *target = argv[++i];
        } else {
            printf("ERROR: No Test String to Include Matches For\n");
            return 1;
        }
    }
    return 0;
}

/* Does `name` contain one of the comma-separated parts of `patterns`? */
static int name_matches(const char *name, const char *patterns)
{
    const char *part = patterns;
    for (;;) {
        const char *end = strchr(part, ',');
        size_t len = end ? (size_t)(end - part) : strlen(part);
        if (len > 0) {
            for (const char *s = name; *s != '\0'; s++) {
                if (strncmp(s, part, len) == 0) {
                    return 1;
                }
            }
        }
        if (end == NULL) {
            return 0;
        }
        part = end + 1;
    }
}

static int test_selected(const char *name)
{
    if (options.include != NULL && !name_matches(name, options.include)) {
        return 0;
    }
    if (options.exclude != NULL && name_matches(name, options.exclude)) {
        return 0;
    }
    return 1;
}

/* Unity prints the file name as given by __FILE__; keep the base name so the
 * output is the same wherever the build tree is. */
static const char *base_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

void UnityBegin(const char *filename)
{
    memset(&unity, 0, sizeof unity);
    unity.file = base_name(filename);
}

int UnityEnd(void)
{
    if (options.list_only) {
        fflush(stdout);
        return 0;
    }
    printf("\n-----------------------\n");
    printf("%u Tests %u Failures %u Ignored \n", unity.tests, unity.failures,
           unity.ignored);
    printf("%s\n", unity.failures == 0 ? "OK" : "FAIL");
    fflush(stdout);
    if ((options.include != NULL || options.exclude != NULL) &&
        options.selected == 0) {
        fprintf(stderr, "no test matches the filter (-n %s -x %s)\n",
                options.include ? options.include : "",
                options.exclude ? options.exclude : "");
        return 1;
    }
    return (int)unity.failures;
}

void UnityDefaultTestRun(UnityTestFunction func, const char *name, int line)
{
    if (!test_selected(name)) {
        return;
    }
    options.selected++;
    if (options.list_only) {
        printf("%s\n", name);
        return;
    }
    unity.test_name = name;
    unity.test_line = line;
    unity.current_failed = 0;
    unity.current_ignored = 0;
    unity.tests++;
    if (TEST_PROTECT()) {
        setUp();
        func();
    }
    if (TEST_PROTECT()) {
        tearDown();
    }
    if (unity.current_failed) {
        unity.failures++;
    } else if (unity.current_ignored) {
        unity.ignored++;
    } else {
        printf("%s:%d:%s:PASS\n", unity.file, line, name);
    }
    fflush(stdout);
}

static void finish_message(const char *message)
{
    if (message != NULL) {
        printf(" %s", message);
    }
    printf("\n");
    fflush(stdout);
}

static void fail_prefix(int line)
{
    printf("%s:%d:%s:FAIL:", unity.file, line,
           unity.test_name ? unity.test_name : "?");
}

/* Marks the test failed and leaves it.  The first failure of a test wins. */
static void abort_test(void)
{
    unity.current_failed = 1;
    longjmp(UnityAbortFrame, 1);
}

void UnityFail(const char *message, int line)
{
    fail_prefix(line);
    finish_message(message);
    abort_test();
}

void UnityIgnore(const char *message, int line)
{
    printf("%s:%d:%s:IGNORE", unity.file, line,
           unity.test_name ? unity.test_name : "?");
    if (message != NULL) {
        printf(": %s", message);
    }
    printf("\n");
    unity.current_ignored = 1;
    longjmp(UnityAbortFrame, 1);
}

void UnityMessage(const char *message, int line)
{
    printf("%s:%d:%s:INFO: %s\n", unity.file, line,
           unity.test_name ? unity.test_name : "?", message ? message : "");
}

void UnityAssertIntWithin(int64_t delta, int64_t expected, int64_t actual,
                          const char *message, int line, int is_unsigned)
{
    int64_t diff = expected > actual ? expected - actual : actual - expected;
    if (diff <= delta) {
        return;
    }
    fail_prefix(line);
    if (delta != 0) {
        printf(" Values Not Within Delta");
    }
    if (is_unsigned) {
        printf(" Expected %llu Was %llu", (unsigned long long)expected,
               (unsigned long long)actual);
    } else {
        printf(" Expected %lld Was %lld", (long long)expected,
               (long long)actual);
    }
    finish_message(message);
    abort_test();
}

static int compare_holds(double threshold, double actual, int op)
{
    switch (op) {
    case UNITY_CMP_LT: return actual < threshold;
    case UNITY_CMP_LE: return actual <= threshold;
    case UNITY_CMP_GT: return actual > threshold;
    case UNITY_CMP_GE: return actual >= threshold;
    default: return 0;
    }
}

static const char *compare_words(int op)
{
    switch (op) {
    case UNITY_CMP_LT: return "less than";
    case UNITY_CMP_LE: return "less than or equal to";
    case UNITY_CMP_GT: return "greater than";
    case UNITY_CMP_GE: return "greater than or equal to";
    default: return "?";
    }
}

void UnityAssertCompareInt(int64_t threshold, int64_t actual, int op,
                           const char *message, int line, int is_unsigned)
{
    int ok;
    if (is_unsigned) {
        uint64_t t = (uint64_t)threshold, a = (uint64_t)actual;
        ok = (op == UNITY_CMP_LT) ? a < t : (op == UNITY_CMP_LE) ? a <= t
           : (op == UNITY_CMP_GT) ? a > t : a >= t;
    } else {
        ok = (op == UNITY_CMP_LT) ? actual < threshold
           : (op == UNITY_CMP_LE) ? actual <= threshold
           : (op == UNITY_CMP_GT) ? actual > threshold : actual >= threshold;
    }
    if (ok) {
        return;
    }
    fail_prefix(line);
    printf(" Expected %s %lld Was %lld", compare_words(op), (long long)threshold,
           (long long)actual);
    finish_message(message);
    abort_test();
}

void UnityAssertDoubleWithin(double delta, double expected, double actual,
                             const char *message, int line)
{
    /* NaN never passes; equal infinities do, as in Unity. */
    if (expected == actual || fabs(expected - actual) <= fabs(delta)) {
        return;
    }
    fail_prefix(line);
    printf(" Values Not Within Delta %.9g Expected %.9g Was %.9g", delta,
           expected, actual);
    finish_message(message);
    abort_test();
}

void UnityAssertFloatWithin(float delta, float expected, float actual,
                            const char *message, int line)
{
    /* float arithmetic, as upstream Unity's UnityAssertFloatsWithin */
    float diff = actual - expected;
    if (diff < 0.0f) {
        diff = -diff;
    }
    float tol = delta < 0.0f ? -delta : delta;
    if (expected == actual || diff <= tol) {
        return;
    }
    fail_prefix(line);
    printf(" Values Not Within Delta %.9g Expected %.9g Was %.9g", (double)delta,
           (double)expected, (double)actual);
    finish_message(message);
    abort_test();
}

void UnityAssertCompareDouble(double threshold, double actual, int op,
                              const char *message, int line)
{
    if (compare_holds(threshold, actual, op)) {
        return;
    }
    fail_prefix(line);
    printf(" Expected %s %.9g Was %.9g", compare_words(op), threshold, actual);
    finish_message(message);
    abort_test();
}

void UnityAssertDoubleClass(double actual, int which, const char *message,
                            int line)
{
    int ok = 0;
    const char *want = "";
    switch (which) {
    case UNITY_CLASS_NAN: ok = isnan(actual); want = "NaN"; break;
    case UNITY_CLASS_NOT_NAN: ok = !isnan(actual); want = "Not NaN"; break;
    case UNITY_CLASS_INF: ok = isinf(actual); want = "Infinity"; break;
    case UNITY_CLASS_DETERMINATE: ok = isfinite(actual); want = "Determinate"; break;
    default: break;
    }
    if (ok) {
        return;
    }
    fail_prefix(line);
    printf(" Expected %s Was %.9g", want, actual);
    finish_message(message);
    abort_test();
}

void UnityAssertEqualString(const char *expected, const char *actual,
                            const char *message, int line)
{
    if (expected != NULL && actual != NULL && strcmp(expected, actual) == 0) {
        return;
    }
    if (expected == NULL && actual == NULL) {
        return;
    }
    fail_prefix(line);
    printf(" Expected '%s' Was '%s'", expected ? expected : "(null)",
           actual ? actual : "(null)");
    finish_message(message);
    abort_test();
}

void UnityAssertEqualMemory(const void *expected, const void *actual,
                            size_t len, const char *message, int line)
{
    const unsigned char *e = expected, *a = actual;
    for (size_t i = 0; i < len; i++) {
        if (e[i] != a[i]) {
            fail_prefix(line);
            printf(" Memory Mismatch. Byte %zu Expected 0x%02X Was 0x%02X", i,
                   e[i], a[i]);
            finish_message(message);
            abort_test();
        }
    }
}
