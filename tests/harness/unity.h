/*
 * A small test harness with Unity's API and output format, written for this
 * project (upstream Unity is not vendored here).  Test files include "unity.h"
 * and use only the macros below, so the same files also build against an
 * upstream Unity checkout: configure with -DHD_UNITY_DIR=/path/to/Unity.
 *
 * Output, as Unity prints it:
 *   file.c:LINE:test_name:PASS
 *   file.c:LINE:test_name:FAIL: message
 *   file.c:LINE:test_name:IGNORE: message
 *   -----------------------
 *   N Tests F Failures I Ignored
 *   OK | FAIL
 *
 * Test selection, as Unity's UNITY_USE_COMMAND_LINE_ARGS runners: a test's
 * main passes argv to UnityParseOptions before UNITY_BEGIN().
 *   -n NAME | -f NAME | -n=NAME   run only tests whose name contains NAME
 *                                 (a comma-separated list: any of them)
 *   -x NAME                       skip tests whose name contains NAME
 *   -l                            list the test names, run nothing
 *   -h                            the options
 * A filter that selects no test fails the run (exit status non-zero), so a
 * misspelt name cannot pass as "0 Tests 0 Failures".
 *
 * A failing assertion ends the current test at once (longjmp), as in Unity.
 * Doubles are always supported here; with upstream Unity the build defines
 * UNITY_INCLUDE_DOUBLE.
 */
#ifndef HD_UNITY_H
#define HD_UNITY_H

#include <setjmp.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef void (*UnityTestFunction)(void);

/* Implemented by each test file, as Unity requires. */
void setUp(void);
void tearDown(void);

int UnityParseOptions(int argc, char **argv);
void UnityBegin(const char *filename);
int UnityEnd(void);
void UnityDefaultTestRun(UnityTestFunction func, const char *name, int line);
void UnityFail(const char *message, int line);
void UnityIgnore(const char *message, int line);
void UnityMessage(const char *message, int line);
void UnityAssertIntWithin(int64_t delta, int64_t expected, int64_t actual,
                          const char *message, int line, int is_unsigned);
void UnityAssertCompareInt(int64_t threshold, int64_t actual, int op,
                           const char *message, int line, int is_unsigned);
void UnityAssertDoubleWithin(double delta, double expected, double actual,
                             const char *message, int line);
void UnityAssertFloatWithin(float delta, float expected, float actual,
                            const char *message, int line);
void UnityAssertCompareDouble(double threshold, double actual, int op,
                              const char *message, int line);
void UnityAssertDoubleClass(double actual, int which, const char *message,
                            int line);
void UnityAssertEqualString(const char *expected, const char *actual,
                            const char *message, int line);
void UnityAssertEqualMemory(const void *expected, const void *actual,
                            size_t len, const char *message, int line);

/* Comparison codes (threshold OP actual reads as "actual OP' threshold"). */
#define UNITY_CMP_LT 1 /* actual <  threshold */
#define UNITY_CMP_LE 2 /* actual <= threshold */
#define UNITY_CMP_GT 3 /* actual >  threshold */
#define UNITY_CMP_GE 4 /* actual >= threshold */

#define UNITY_CLASS_NAN 1
#define UNITY_CLASS_NOT_NAN 2
#define UNITY_CLASS_INF 3
#define UNITY_CLASS_DETERMINATE 4

extern jmp_buf UnityAbortFrame;
#define TEST_PROTECT() (setjmp(UnityAbortFrame) == 0)

#define UNITY_BEGIN() UnityBegin(__FILE__)
#define UNITY_END() UnityEnd()
#define RUN_TEST(func) UnityDefaultTestRun(func, #func, __LINE__)

#define TEST_FAIL_MESSAGE(m) UnityFail((m), __LINE__)
#define TEST_FAIL() UnityFail(NULL, __LINE__)
#define TEST_IGNORE_MESSAGE(m) UnityIgnore((m), __LINE__)
#define TEST_IGNORE() UnityIgnore(NULL, __LINE__)
#define TEST_MESSAGE(m) UnityMessage((m), __LINE__)
#define TEST_PASS() ((void)0)

#define TEST_ASSERT_MESSAGE(c, m) do { if (!(c)) UnityFail((m) ? (m) : "Expression Evaluated To FALSE", __LINE__); } while (0)
#define TEST_ASSERT(c) TEST_ASSERT_MESSAGE((c), "Expression Evaluated To FALSE")
#define TEST_ASSERT_TRUE(c) TEST_ASSERT_MESSAGE((c), "Expected TRUE Was FALSE")
#define TEST_ASSERT_TRUE_MESSAGE(c, m) TEST_ASSERT_MESSAGE((c), (m))
#define TEST_ASSERT_FALSE(c) TEST_ASSERT_MESSAGE(!(c), "Expected FALSE Was TRUE")
#define TEST_ASSERT_FALSE_MESSAGE(c, m) TEST_ASSERT_MESSAGE(!(c), (m))
#define TEST_ASSERT_NULL(p) TEST_ASSERT_MESSAGE((p) == NULL, "Expected NULL")
#define TEST_ASSERT_NOT_NULL(p) TEST_ASSERT_MESSAGE((p) != NULL, "Expected Non-NULL")
#define TEST_ASSERT_NULL_MESSAGE(p, m) TEST_ASSERT_MESSAGE((p) == NULL, (m))
#define TEST_ASSERT_NOT_NULL_MESSAGE(p, m) TEST_ASSERT_MESSAGE((p) != NULL, (m))

/* Integers */
#define UNITY_INT_EQ(e, a, m, u) UnityAssertIntWithin(0, (int64_t)(e), (int64_t)(a), (m), __LINE__, (u))
#define TEST_ASSERT_EQUAL_INT_MESSAGE(e, a, m) UNITY_INT_EQ(e, a, m, 0)
#define TEST_ASSERT_EQUAL_INT(e, a) UNITY_INT_EQ(e, a, NULL, 0)
#define TEST_ASSERT_EQUAL(e, a) UNITY_INT_EQ(e, a, NULL, 0)
#define TEST_ASSERT_EQUAL_MESSAGE(e, a, m) UNITY_INT_EQ(e, a, m, 0)
#define TEST_ASSERT_EQUAL_INT8(e, a) UNITY_INT_EQ(e, a, NULL, 0)
#define TEST_ASSERT_EQUAL_INT16(e, a) UNITY_INT_EQ(e, a, NULL, 0)
#define TEST_ASSERT_EQUAL_INT32(e, a) UNITY_INT_EQ(e, a, NULL, 0)
#define TEST_ASSERT_EQUAL_INT32_MESSAGE(e, a, m) UNITY_INT_EQ(e, a, m, 0)
#define TEST_ASSERT_EQUAL_INT64(e, a) UNITY_INT_EQ(e, a, NULL, 0)
#define TEST_ASSERT_EQUAL_UINT(e, a) UNITY_INT_EQ(e, a, NULL, 1)
#define TEST_ASSERT_EQUAL_UINT_MESSAGE(e, a, m) UNITY_INT_EQ(e, a, m, 1)
#define TEST_ASSERT_EQUAL_UINT8(e, a) UNITY_INT_EQ(e, a, NULL, 1)
#define TEST_ASSERT_EQUAL_UINT8_MESSAGE(e, a, m) UNITY_INT_EQ(e, a, m, 1)
#define TEST_ASSERT_EQUAL_UINT16(e, a) UNITY_INT_EQ(e, a, NULL, 1)
#define TEST_ASSERT_EQUAL_UINT16_MESSAGE(e, a, m) UNITY_INT_EQ(e, a, m, 1)
#define TEST_ASSERT_EQUAL_UINT32(e, a) UNITY_INT_EQ(e, a, NULL, 1)
#define TEST_ASSERT_EQUAL_UINT32_MESSAGE(e, a, m) UNITY_INT_EQ(e, a, m, 1)
#define TEST_ASSERT_EQUAL_UINT64(e, a) UNITY_INT_EQ(e, a, NULL, 1)
#define TEST_ASSERT_EQUAL_HEX8(e, a) UNITY_INT_EQ(e, a, NULL, 1)
#define TEST_ASSERT_EQUAL_HEX16(e, a) UNITY_INT_EQ(e, a, NULL, 1)
#define TEST_ASSERT_EQUAL_HEX32(e, a) UNITY_INT_EQ(e, a, NULL, 1)
#define TEST_ASSERT_EQUAL_HEX32_MESSAGE(e, a, m) UNITY_INT_EQ(e, a, m, 1)
#define TEST_ASSERT_EQUAL_size_t(e, a) UNITY_INT_EQ(e, a, NULL, 1)
#define TEST_ASSERT_INT_WITHIN(d, e, a) UnityAssertIntWithin((int64_t)(d), (int64_t)(e), (int64_t)(a), NULL, __LINE__, 0)
#define TEST_ASSERT_INT_WITHIN_MESSAGE(d, e, a, m) UnityAssertIntWithin((int64_t)(d), (int64_t)(e), (int64_t)(a), (m), __LINE__, 0)
#define TEST_ASSERT_UINT32_WITHIN(d, e, a) UnityAssertIntWithin((int64_t)(d), (int64_t)(e), (int64_t)(a), NULL, __LINE__, 1)
#define TEST_ASSERT_LESS_THAN(t, a) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_CMP_LT, NULL, __LINE__, 0)
#define TEST_ASSERT_LESS_THAN_MESSAGE(t, a, m) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_CMP_LT, (m), __LINE__, 0)
#define TEST_ASSERT_LESS_OR_EQUAL(t, a) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_CMP_LE, NULL, __LINE__, 0)
#define TEST_ASSERT_LESS_OR_EQUAL_MESSAGE(t, a, m) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_CMP_LE, (m), __LINE__, 0)
#define TEST_ASSERT_GREATER_THAN(t, a) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_CMP_GT, NULL, __LINE__, 0)
#define TEST_ASSERT_GREATER_THAN_MESSAGE(t, a, m) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_CMP_GT, (m), __LINE__, 0)
#define TEST_ASSERT_GREATER_OR_EQUAL(t, a) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_CMP_GE, NULL, __LINE__, 0)
#define TEST_ASSERT_GREATER_OR_EQUAL_MESSAGE(t, a, m) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_CMP_GE, (m), __LINE__, 0)
#define TEST_ASSERT_LESS_THAN_UINT32(t, a) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_CMP_LT, NULL, __LINE__, 1)
#define TEST_ASSERT_GREATER_THAN_UINT32(t, a) UnityAssertCompareInt((int64_t)(t), (int64_t)(a), UNITY_CMP_GT, NULL, __LINE__, 1)

/* Floating point.  As in upstream Unity, FLOAT assertions convert their
 * arguments to float and compare in float; DOUBLE ones work in double. */
#define TEST_ASSERT_FLOAT_WITHIN(d, e, a) UnityAssertFloatWithin((float)(d), (float)(e), (float)(a), NULL, __LINE__)
#define TEST_ASSERT_FLOAT_WITHIN_MESSAGE(d, e, a, m) UnityAssertFloatWithin((float)(d), (float)(e), (float)(a), (m), __LINE__)
#define TEST_ASSERT_DOUBLE_WITHIN(d, e, a) UnityAssertDoubleWithin((double)(d), (double)(e), (double)(a), NULL, __LINE__)
#define TEST_ASSERT_DOUBLE_WITHIN_MESSAGE(d, e, a, m) UnityAssertDoubleWithin((double)(d), (double)(e), (double)(a), (m), __LINE__)
#define TEST_ASSERT_EQUAL_FLOAT(e, a) UnityAssertFloatWithin(1e-5f * ((float)(e) < 0 ? -(float)(e) : (float)(e)), (float)(e), (float)(a), NULL, __LINE__)
#define TEST_ASSERT_EQUAL_FLOAT_MESSAGE(e, a, m) UnityAssertFloatWithin(1e-5f * ((float)(e) < 0 ? -(float)(e) : (float)(e)), (float)(e), (float)(a), (m), __LINE__)
#define TEST_ASSERT_EQUAL_DOUBLE(e, a) UnityAssertDoubleWithin(1e-12 * ((double)(e) < 0 ? -(double)(e) : (double)(e)) + 1e-300, (double)(e), (double)(a), NULL, __LINE__)
#define TEST_ASSERT_LESS_THAN_FLOAT(t, a) UnityAssertCompareDouble((double)(float)(t), (double)(float)(a), UNITY_CMP_LT, NULL, __LINE__)
#define TEST_ASSERT_LESS_THAN_FLOAT_MESSAGE(t, a, m) UnityAssertCompareDouble((double)(float)(t), (double)(float)(a), UNITY_CMP_LT, (m), __LINE__)
#define TEST_ASSERT_LESS_OR_EQUAL_FLOAT(t, a) UnityAssertCompareDouble((double)(float)(t), (double)(float)(a), UNITY_CMP_LE, NULL, __LINE__)
#define TEST_ASSERT_LESS_OR_EQUAL_FLOAT_MESSAGE(t, a, m) UnityAssertCompareDouble((double)(float)(t), (double)(float)(a), UNITY_CMP_LE, (m), __LINE__)
#define TEST_ASSERT_GREATER_THAN_FLOAT(t, a) UnityAssertCompareDouble((double)(float)(t), (double)(float)(a), UNITY_CMP_GT, NULL, __LINE__)
#define TEST_ASSERT_GREATER_THAN_FLOAT_MESSAGE(t, a, m) UnityAssertCompareDouble((double)(float)(t), (double)(float)(a), UNITY_CMP_GT, (m), __LINE__)
#define TEST_ASSERT_GREATER_OR_EQUAL_FLOAT(t, a) UnityAssertCompareDouble((double)(float)(t), (double)(float)(a), UNITY_CMP_GE, NULL, __LINE__)
#define TEST_ASSERT_GREATER_OR_EQUAL_FLOAT_MESSAGE(t, a, m) UnityAssertCompareDouble((double)(float)(t), (double)(float)(a), UNITY_CMP_GE, (m), __LINE__)
#define TEST_ASSERT_LESS_THAN_DOUBLE(t, a) UnityAssertCompareDouble((double)(t), (double)(a), UNITY_CMP_LT, NULL, __LINE__)
#define TEST_ASSERT_LESS_THAN_DOUBLE_MESSAGE(t, a, m) UnityAssertCompareDouble((double)(t), (double)(a), UNITY_CMP_LT, (m), __LINE__)
#define TEST_ASSERT_GREATER_THAN_DOUBLE(t, a) UnityAssertCompareDouble((double)(t), (double)(a), UNITY_CMP_GT, NULL, __LINE__)
#define TEST_ASSERT_FLOAT_IS_NAN(a) UnityAssertDoubleClass((double)(a), UNITY_CLASS_NAN, NULL, __LINE__)
#define TEST_ASSERT_FLOAT_IS_NOT_NAN(a) UnityAssertDoubleClass((double)(a), UNITY_CLASS_NOT_NAN, NULL, __LINE__)
#define TEST_ASSERT_FLOAT_IS_INF(a) UnityAssertDoubleClass((double)(a), UNITY_CLASS_INF, NULL, __LINE__)
#define TEST_ASSERT_FLOAT_IS_DETERMINATE(a) UnityAssertDoubleClass((double)(float)(a), UNITY_CLASS_DETERMINATE, NULL, __LINE__)
#define TEST_ASSERT_FLOAT_IS_DETERMINATE_MESSAGE(a, m) UnityAssertDoubleClass((double)(float)(a), UNITY_CLASS_DETERMINATE, (m), __LINE__)
#define TEST_ASSERT_DOUBLE_IS_DETERMINATE(a) UnityAssertDoubleClass((double)(a), UNITY_CLASS_DETERMINATE, NULL, __LINE__)

/* Strings and memory */
#define TEST_ASSERT_EQUAL_STRING(e, a) UnityAssertEqualString((e), (a), NULL, __LINE__)
#define TEST_ASSERT_EQUAL_STRING_MESSAGE(e, a, m) UnityAssertEqualString((e), (a), (m), __LINE__)
#define TEST_ASSERT_EQUAL_MEMORY(e, a, n) UnityAssertEqualMemory((e), (a), (n), NULL, __LINE__)
#define TEST_ASSERT_EQUAL_MEMORY_MESSAGE(e, a, n, m) UnityAssertEqualMemory((e), (a), (n), (m), __LINE__)

#ifdef __cplusplus
}
#endif

#endif /* HD_UNITY_H */
