/* Base layer: JSON values that are valid whatever they hold (the one writer of strings and
 * numbers for every JSON file i2m and its tools write). */
#include "i2m/base.h"

#include <math.h>

void i2m_json_number(FILE *f, double x)
{
  if (isfinite(x)) fprintf(f, "%.17g", x);
  else fputs("null", f);
}

void i2m_json_member(FILE *f, const char *key, double x, bool last)
{
  fprintf(f, "\"%s\": ", key);
  i2m_json_number(f, x);
  if (!last) fputs(", ", f);
}

/* The length of the valid UTF-8 sequence at s (1-4), or 0 when the bytes there are not one
 * (overlong forms, surrogates and code points above U+10FFFF are not). */
static int utf8_length(const unsigned char *s)
{
  const unsigned char c = s[0];
  int n;
  unsigned cp;
  if (c < 0x80) return 1;
  if ((c & 0xE0) == 0xC0) n = 2, cp = c & 0x1F;
  else if ((c & 0xF0) == 0xE0) n = 3, cp = c & 0x0F;
  else if ((c & 0xF8) == 0xF0) n = 4, cp = c & 0x07;
  else return 0;
  for (int k = 1; k < n; k++) {
    if ((s[k] & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (s[k] & 0x3F);
  }
  static const unsigned least[5] = {0, 0, 0x80, 0x800, 0x10000};
  if (cp < least[n] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return n;
}

void i2m_json_string(FILE *f, const char *s)
{
  fputc('"', f);
  const unsigned char *p = (const unsigned char *)(s ? s : "");
  while (*p) {
    const int n = utf8_length(p);
    if (n == 0) { /* (a byte that is not UTF-8: the replacement character) */
      fputs("\\ufffd", f);
      p++;
    } else if (*p == '"' || *p == '\\') {
      fprintf(f, "\\%c", *p++);
    } else if (*p < 0x20 || *p == 0x7f) {
      fprintf(f, "\\u%04x", *p++);
    } else {
      fwrite(p, 1, (size_t)n, f);
      p += n;
    }
  }
  fputc('"', f);
}
