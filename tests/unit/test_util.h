/* Shared helpers for the CUnit test programs: a main() that runs the suites a test file
 * declares, and the location of the real data. */
#ifndef I2M_TEST_UTIL_H
#define I2M_TEST_UTIL_H

#include <CUnit/Basic.h>
#include <CUnit/CUnit.h>
#include <stdio.h>
#include <stdlib.h>

typedef struct {
  const char *name;
  void (*fn)(void);
} test_case_t;

/* Runs one suite made of the given cases; returns the process exit code. */
static inline int test_run_suite(const char *suite, const test_case_t *cases, int ncases)
{
  if (CU_initialize_registry() != CUE_SUCCESS) return 2;
  CU_pSuite s = CU_add_suite(suite, NULL, NULL);
  for (int i = 0; i < ncases; i++) CU_add_test(s, cases[i].name, cases[i].fn);
  CU_basic_set_mode(CU_BRM_VERBOSE);
  CU_basic_run_tests();
  unsigned failed = CU_get_number_of_failures() + CU_get_number_of_tests_failed();
  unsigned run = CU_get_number_of_tests_run();
  CU_cleanup_registry();
  return (failed == 0 && run == (unsigned)ncases) ? 0 : 1;
}

/* Directory of the real images (../shared/data from the project root, or $I2M_DATA). */
static inline const char *test_data_dir(void)
{
  const char *d = getenv("I2M_DATA");
  return d ? d : "../shared/data";
}

#define TEST_MAIN(suite, cases) \
  int main(void) { return test_run_suite(suite, cases, (int)(sizeof cases / sizeof cases[0])); }

#endif
