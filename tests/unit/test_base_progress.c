/* Base layer: progress lines and error messages.  i2m_progress_add from the threads of an OpenMP loop counts
 * every item exactly once and prints whole lines ("phase: N of TOTAL ..., about S s left"),
 * one at a time; --quiet (I2M_LOG_QUIET) silences them.  stderr is redirected to a file
 * for the checks; the interval is shortened so that the test does not wait 2 s. */
#include <stdatomic.h>
#include <string.h>
#include <unistd.h>

#include "i2m/base.h"
#include "test_util.h"

#define THREADS 4
#define ITEMS 200000
#define STEP 64

/* Runs the loop with stderr in a temporary file; returns the file's text (owned) and the
 * final count in *done. */
static char *run_loop(i2m_log_level_t level, int64_t *done)
{
  char path[] = "/tmp/i2m_progress_XXXXXX";
  const int fd = mkstemp(path);
  CU_ASSERT_FATAL(fd >= 0);
  fflush(stderr);
  const int saved = dup(2);
  dup2(fd, 2);
  i2m_log_set_level(level);
  i2m_progress_t pg;
  i2m_progress_begin_total(&pg, "test phase", "items", ITEMS);
  pg.interval = 1e-4; /* (a line nearly every time a thread looks) */
  const double t0 = i2m_wtime();
  I2M_OMP(omp parallel for num_threads(THREADS) schedule(dynamic, 256))
  for (int64_t i = 0; i < ITEMS; i++) {
    if ((i & (STEP - 1)) == STEP - 1) {
      i2m_progress_add(&pg, STEP);
      while (i2m_wtime() - t0 < 1e-6 * (double)i) { /* (about 0.2 s in all: lines at several counts) */
      }
    }
  }
  /* (an atomic load: ThreadSanitizer does not see the OpenMP runtime's barrier) */
  *done = atomic_load_explicit((_Atomic int64_t *)&pg.done, memory_order_relaxed);
  i2m_progress_end(&pg, *done);
  fflush(stderr);
  dup2(saved, 2);
  close(saved);
  i2m_log_set_level(I2M_LOG_INFO);
  FILE *f = fopen(path, "rb");
  CU_ASSERT_FATAL(f != NULL);
  char *text = calloc(1, 1 << 22);
  CU_ASSERT_FATAL(text != NULL);
  size_t n = fread(text, 1, (1 << 22) - 1, f);
  text[n] = '\0';
  fclose(f);
  unlink(path);
  close(fd);
  return text;
}

static void test_progress_add_threads(void)
{
  int64_t done = 0;
  char *text = run_loop(I2M_LOG_INFO, &done);
  CU_ASSERT_EQUAL(done, ITEMS); /* every item counted once */
  int lines = 0, done_lines = 0;
  for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
    lines++;
    CU_ASSERT(strncmp(line, "test phase", 10) == 0); /* whole lines, never mixed */
    if (strncmp(line, "test phase done", 15) == 0) {
      done_lines++;
      continue;
    }
    long long count = 0, total = 0;
    CU_ASSERT(sscanf(line, "test phase: %lld of %lld items", &count, &total) == 2);
    CU_ASSERT(count > 0 && count <= ITEMS && total == ITEMS);
    CU_ASSERT(strstr(line, "s left") != NULL);
  }
  CU_ASSERT(lines >= 3);
  CU_ASSERT_EQUAL(done_lines, 1);
  free(text);
}

static void test_progress_quiet(void)
{
  int64_t done = 0;
  char *text = run_loop(I2M_LOG_QUIET, &done);
  CU_ASSERT_EQUAL(done, ITEMS);
  CU_ASSERT_STRING_EQUAL(text, ""); /* --quiet: not a line */
  free(text);
}

/* (debug builds append " [file:line]" to every message) */
static bool starts_with(const char *s, const char *prefix) { return strncmp(s, prefix, strlen(prefix)) == 0; }

/* An error that quotes the one before it (a caller adds context to its callee's message)
 * gets both, whole: the message once came out as its own prefix and a torn tail. */
static void test_error_quotes_previous(void)
{
  i2m_err_t code = I2M_ERROR(I2M_ERR_MEMORY, "out of memory growing an array to %d bytes", 24600);
  CU_ASSERT_EQUAL(code, I2M_ERR_MEMORY);
  I2M_ERROR(I2M_ERR_INTERNAL, "refinement failed in a tile: %s", i2m_error_message());
  CU_ASSERT(starts_with(i2m_error_message(), "refinement failed in a tile: out of memory growing an array to 24600 bytes"));
  I2M_ERROR(I2M_ERR_INPUT, "bad\nline\033[2J");
  CU_ASSERT(starts_with(i2m_error_message(), "bad?line?[2J")); /* one line, no terminal commands */
}

static const test_case_t cases[] = {
    {"progress from the threads of a loop", test_progress_add_threads},
    {"--quiet silences progress", test_progress_quiet},
    {"an error message that quotes the previous one", test_error_quotes_previous},
};
TEST_MAIN("progress lines and error messages", cases)
