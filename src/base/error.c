/* Base layer: thread-local error messages, error names and the fatal abort path. */
#include "i2m/base.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static _Thread_local char error_message[1024];
static void (*abort_hook)(void);

i2m_err_t i2m_error_set(i2m_err_t code, const char *file, int line, const char *fmt, ...)
{
  /* (formatted apart first: a message may quote the one it replaces) */
  char msg[sizeof error_message];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  memcpy(error_message, msg, sizeof msg);
  /* Messages quote text from bad files: a control character (a newline, a terminal escape)
   * would break the one-line message or reach the user's terminal as a command. */
  for (char *c = error_message; *c; c++)
    if ((unsigned char)*c < 0x20 || *c == 0x7f) *c = '?';
#ifdef I2M_DEBUG
  size_t n = strlen(error_message);
  snprintf(error_message + n, sizeof error_message - n, " [%s:%d]", file, line);
#else
  (void)file;
  (void)line;
#endif
  return code;
}

const char *i2m_error_message(void) { return error_message; }

void i2m_error_clear(void) { error_message[0] = '\0'; }

const char *i2m_error_name(i2m_err_t code)
{
  switch (code) {
  case I2M_OK: return "success";
  case I2M_ERR_INPUT: return "bad input";
  case I2M_ERR_IO: return "I/O error";
  case I2M_ERR_MEMORY: return "out of memory";
  case I2M_ERR_UNSUPPORTED: return "unsupported";
  case I2M_ERR_ARG: return "bad argument";
  case I2M_ERR_INTERNAL: return "internal error";
  }
  return "unknown error";
}

void i2m_abort_set_hook(void (*hook)(void)) { abort_hook = hook; }

void i2m_abort(const char *file, int line, const char *fmt, ...)
{
  char msg[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  fprintf(stderr, "[i2m] %s:%d %s\n", file, line, msg);
  fflush(stderr);
  if (abort_hook) abort_hook();
  abort();
}
