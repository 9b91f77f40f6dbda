/* i2m base layer (layer 0): index types, error codes and error propagation, checked
 * allocation, logging with verbosity and progress lines, wall-clock timers and memory
 * figures.  Uses libc only; every other layer includes this header. */
#ifndef I2M_BASE_H
#define I2M_BASE_H

#include <stddef.h>
#include <stdint.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/** Index local to one process (vertex and tetrahedron ids in a process's arrays). */
typedef int32_t i2m_lidx_t;
/** Index global across ranks (vertex global ids, used by symbolic perturbation). */
typedef int64_t i2m_gidx_t;

/** Error codes returned by every fallible function (0 = success). */
typedef enum {
  I2M_OK = 0,
  I2M_ERR_INPUT,       /**< bad input file: corrupt, truncated, inconsistent header */
  I2M_ERR_IO,          /**< the operating system refused (missing file, directory, disk full) */
  I2M_ERR_MEMORY,      /**< allocation failed or a size limit was exceeded */
  I2M_ERR_UNSUPPORTED, /**< a valid file or request that i2m does not handle */
  I2M_ERR_ARG,         /**< bad command-line option or parameter */
  I2M_ERR_INTERNAL     /**< a bug detected at run time */
} i2m_err_t;

#if defined(__GNUC__) || defined(__clang__)
#define I2M_PRINTF(f, a) __attribute__((format(printf, f, a)))
#define I2M_LIKELY(x) __builtin_expect(!!(x), 1)
#define I2M_UNLIKELY(x) __builtin_expect(!!(x), 0)
#define I2M_NOINLINE __attribute__((noinline))
#define I2M_PREFETCH(addr) __builtin_prefetch(addr)
#define I2M_PREFETCH_WRITE(addr) __builtin_prefetch(addr, 1)
#define I2M_INLINE inline __attribute__((always_inline)) /* hot-path helpers the compiler would call */
#else
#define I2M_INLINE inline
#define I2M_PREFETCH(addr) ((void)0)
#define I2M_PREFETCH_WRITE(addr) ((void)0)
#define I2M_NOINLINE
#define I2M_PRINTF(f, a)
#define I2M_LIKELY(x) (x)
#define I2M_UNLIKELY(x) (x)
#endif

/** Records an error message (printf-style) for the calling thread and returns @p code.
 *  Not collective.  Thread safe: the message buffer is thread-local. */
i2m_err_t i2m_error_set(i2m_err_t code, const char *file, int line, const char *fmt, ...)
    I2M_PRINTF(4, 5);
/** The calling thread's last error message ("" if none).  Borrowed, valid until the next error. */
const char *i2m_error_message(void);
/** Clears the calling thread's error message. */
void i2m_error_clear(void);
/** A short English name for an error code. */
const char *i2m_error_name(i2m_err_t code);

/** Raise a recoverable error with a message a user can act on. */
#define I2M_ERROR(code, ...) i2m_error_set((code), __FILE__, __LINE__, __VA_ARGS__)
/** If @p cond is false, record the message and return @p code from the calling function. */
#define I2M_CHECK(cond, code, ...)                                                          \
  do {                                                                                      \
    if (I2M_UNLIKELY(!(cond))) return i2m_error_set((code), __FILE__, __LINE__, __VA_ARGS__); \
  } while (0)
/** Call a fallible function and return its error code on failure (message already set). */
#define I2M_CALL(call)                                                                      \
  do {                                                                                      \
    i2m_err_t i2m_call_err_ = (call);                                                       \
    if (I2M_UNLIKELY(i2m_call_err_ != I2M_OK)) return i2m_call_err_;                        \
  } while (0)
/** Like I2M_CALL but jumps to a cleanup label with the code stored in @p err. */
#define I2M_CALL_GOTO(err, label, call)                                                     \
  do {                                                                                      \
    (err) = (call);                                                                         \
    if (I2M_UNLIKELY((err) != I2M_OK)) goto label;                                          \
  } while (0)
/** Like I2M_CHECK but jumps to a cleanup label. */
#define I2M_CHECK_GOTO(cond, err, label, code, ...)                                         \
  do {                                                                                      \
    if (I2M_UNLIKELY(!(cond))) {                                                            \
      (err) = i2m_error_set((code), __FILE__, __LINE__, __VA_ARGS__);                       \
      goto label;                                                                           \
    }                                                                                       \
  } while (0)

/** Prints "[i2m] file:line message" to stderr and aborts the process (MPI_Abort when the
 *  dist layer installed its abort hook).  For broken invariants only. */
void i2m_abort(const char *file, int line, const char *fmt, ...) I2M_PRINTF(3, 4);
/** Installs a function called by i2m_abort before abort() (the dist layer calls MPI_Abort). */
void i2m_abort_set_hook(void (*hook)(void));
/** Always-on invariant check. */
#define I2M_CHECK_ABORT(cond, ...)                                                          \
  do {                                                                                      \
    if (I2M_UNLIKELY(!(cond))) i2m_abort(__FILE__, __LINE__, __VA_ARGS__);                 \
  } while (0)
/** Debug-only invariant check (free in release builds, fine in hot loops). */
#ifdef I2M_DEBUG
#define I2M_ASSERT(cond) I2M_CHECK_ABORT(cond, "assertion failed: %s", #cond)
#else
#define I2M_ASSERT(cond) ((void)0)
#endif

/* ---- allocation: every call sets an error message and returns I2M_ERR_MEMORY on failure ---- */

/** *out = malloc(n * size); overflow-checked.  Zero n gives a NULL pointer and I2M_OK. */
i2m_err_t i2m_malloc(size_t n, size_t size, void *out);
/** *out = calloc(n, size). */
i2m_err_t i2m_calloc(size_t n, size_t size, void *out);
/** *ptr = realloc(*ptr, n * size); on failure *ptr is left valid. */
i2m_err_t i2m_realloc(size_t n, size_t size, void *ptr);
/** Programs call this first: large arrays get their own mappings (glibc; no-op elsewhere),
 *  so that growing and freeing them changes the resident memory as expected. */
void i2m_malloc_tune(void);
/** free(*ptr); *ptr = NULL.  Accepts NULL. */
void i2m_free(void *ptr);
/** i2m_realloc for the large, randomly accessed arrays (the mesh).  With the environment
 *  variable I2M_HUGEPAGES=1, blocks of several MB are advised to use transparent huge pages
 *  where the system offers them (Linux madvise(MADV_HUGEPAGE); a no-op elsewhere): random
 *  access over hundreds of MB then misses the TLB less often, and first touches fault 2 MB at
 *  a time, which some machines make dearer than it saves. */
i2m_err_t i2m_realloc_large(size_t n, size_t size, void *ptr);

/* ---- a space-filling curve ---- */

/** The Morton code of the cell of point x in a grid of 2^bits cells along each axis (bits at
 *  most 10), cell (i, j, k) = floor((x - lo) * scale) clamped to the grid (NaN: 0). */
uint32_t i2m_morton_code(const double x[3], const double lo[3], const double scale[3], int bits);
/** Sorts the words a[0..n) (code << 32 | payload) by the low `bits` bits of their codes: a
 *  stable counting sort, 9 bits a pass, least significant first, with b (n words) as scratch.
 *  Returns a or b, whichever holds the sorted words. */
uint64_t *i2m_sort_by_code(uint64_t *a, uint64_t *b, size_t n, int bits);

/* ---- output files ---- */

/** An output file written under a temporary name beside @p path and renamed into place by
 *  i2m_outfile_commit: a failed or interrupted run never leaves a partial file under the
 *  final name, and never harms the previous file of that name. */
typedef struct {
  FILE *f;    /**< write here (fwrite, fprintf) */
  char *path; /**< the final name (owned) */
  char *tmp;  /**< the temporary name (owned) */
  int slot;   /**< its place in the list of temporaries removed on a signal */
} i2m_outfile_t;
/** Opens the temporary with fopen's @p mode ("w" or "wb"). */
i2m_err_t i2m_outfile_open(i2m_outfile_t *o, const char *path, const char *mode);
/** Flushes and closes, and renames it into place when every write succeeded; otherwise
 *  removes the temporary and returns an I/O error naming the file. */
i2m_err_t i2m_outfile_commit(i2m_outfile_t *o);
/** Closes and removes the temporary (after a failure elsewhere). */
void i2m_outfile_abandon(i2m_outfile_t *o);
/** Programs call this once: SIGINT, SIGTERM and SIGHUP remove the temporaries being written
 *  before they end the process; SIGXFSZ is ignored (a file-size limit fails the write). */
void i2m_outfile_signals(void);
/** The directory part of @p path into dir[cap]: "." when it has none, "/" for the root.
 *  False when it does not fit. */
bool i2m_path_dir(const char *path, char *dir, size_t cap);
/** True when @p a and @p b name the same file (device and inode; for files not yet there,
 *  the same name in the same directory). */
bool i2m_same_file(const char *a, const char *b);

/* ---- JSON ---- */

/** Writes x as a JSON number, or null when it is not finite (JSON has no NaN or infinity). */
void i2m_json_number(FILE *f, double x);
/** Writes s as a JSON string: quotes, backslashes and control characters escaped, bytes that
 *  are not UTF-8 written as U+FFFD.  NULL writes "". */
void i2m_json_string(FILE *f, const char *s);
/** Writes "key": x (i2m_json_number), then ", " unless @p last. */
void i2m_json_member(FILE *f, const char *key, double x, bool last);

/* ---- logging ---- */

typedef enum { I2M_LOG_QUIET = 0, I2M_LOG_WARN = 1, I2M_LOG_INFO = 2, I2M_LOG_DEBUG = 3 } i2m_log_level_t;
/** Sets the process-wide verbosity (default I2M_LOG_INFO).  Call before starting threads. */
void i2m_log_set_level(i2m_log_level_t level);
i2m_log_level_t i2m_log_get_level(void);
/** Sets a prefix such as "[rank 3] " for every line (default none).  Copied. */
void i2m_log_set_prefix(const char *prefix);
/** Prints one line to stderr when the verbosity allows it.  Thread safe (one fprintf). */
void i2m_log(i2m_log_level_t level, const char *fmt, ...) I2M_PRINTF(2, 3);
#define i2m_info(...) i2m_log(I2M_LOG_INFO, __VA_ARGS__)
#define i2m_warn(...) i2m_log(I2M_LOG_WARN, __VA_ARGS__)
#define i2m_debug(...) i2m_log(I2M_LOG_DEBUG, __VA_ARGS__)

/** Progress of a long phase: prints "phase: N items, rate/s, elapsed" on stderr at most every
 *  @p interval s (2), and "N of TOTAL (P%), ..., about S s left" when the total is known. */
typedef struct {
  const char *phase; /* borrowed */
  const char *unit;  /* borrowed, e.g. "tets" */
  double t_start, t_last, interval;
  int64_t total;     /* the count at the end, or 0 when unknown */
  int64_t done;      /* the count so far, for i2m_progress_add (atomic) */
  int busy;          /* i2m_progress_add: a thread is printing (atomic) */
} i2m_progress_t;
void i2m_progress_begin(i2m_progress_t *p, const char *phase, const char *unit);
/** The same for a phase whose final count is known (an estimate of the time left is shown). */
void i2m_progress_begin_total(i2m_progress_t *p, const char *phase, const char *unit, int64_t total);
/** Cheap to call often: looks at the clock and prints only when the interval has passed. */
void i2m_progress_update(i2m_progress_t *p, int64_t count);
void i2m_progress_end(i2m_progress_t *p, int64_t count);
/** For loops run by several threads: adds @p n items to the count (an atomic add: call it
 *  every few thousand items); the calling thread prints the line when the interval has passed
 *  and no other thread is doing so (a try-lock: nobody waits).  Thread safe. */
void i2m_progress_add(i2m_progress_t *p, int64_t n);

/* ---- timers and memory ---- */

/** Monotonic wall-clock time in seconds. */
double i2m_wtime(void);
/** Peak resident set size of the process in bytes (0 if unknown). */
size_t i2m_peak_rss_bytes(void);
/** Current resident set size in bytes (0 if unknown). */
size_t i2m_current_rss_bytes(void);
/** The memory this process may use: the machine's physical memory, lowered by the process
 *  limits (RLIMIT_AS, RLIMIT_DATA) when they are set.  0 if unknown. */
double i2m_memory_limit_bytes(void);

/* ---- OpenMP outside src/threads goes through these (no-ops without OpenMP) ---- */
#ifdef _OPENMP
#define I2M_OMP(directive) _Pragma(#directive)
#else
#define I2M_OMP(directive)
#endif

/* ---- small helpers ---- */
#define I2M_PI 3.14159265358979323846

/** One step of Marsaglia's xorshift64 (state non-zero): cheap reproducible randomness. */
static inline uint64_t i2m_xorshift64(uint64_t *state)
{
  uint64_t x = *state;
  x ^= x << 13;
  x ^= x >> 7;
  x ^= x << 17;
  return *state = x;
}
static inline double i2m_sq(double x) { return x * x; }
static inline int64_t i2m_min_i64(int64_t a, int64_t b) { return a < b ? a : b; }
static inline int64_t i2m_max_i64(int64_t a, int64_t b) { return a > b ? a : b; }

#ifdef __cplusplus
}
#endif
#endif
