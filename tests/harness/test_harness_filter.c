/* The harness's name filter (-n/-x, unity.h), checked by the CTest tests in
 * tests/harness/CMakeLists.txt against the names and counts it prints. */
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static void test_alpha(void) { TEST_ASSERT_EQUAL_INT(1, 1); }
static void test_beta(void) { TEST_ASSERT_EQUAL_INT(2, 2); }
static void test_beta_more(void) { TEST_ASSERT_EQUAL_INT(3, 3); }

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_alpha);
    RUN_TEST(test_beta);
    RUN_TEST(test_beta_more);
    return UNITY_END();
}
