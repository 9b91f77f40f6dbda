/* i2m-check: one colour per label for the pictures (plot.c), every two of them told apart.
 *   A label keeps the colour of the 3D Slicer colour table beside the image (<stem>.ctbl, read
 *   with the image: img->names)
 *   when that colour lies at least CK_MIN_DELTA_E (CIE76 distance in CIELAB, D65) from the
 *   background (white) and from the table colours kept before it (labels in increasing
 *   order: of two clashing labels the smaller keeps its colour).  Every other label gets the
 *   candidate colour farthest from all colours given so far and from the background
 *   (farthest-point choice over a 16-level sRGB grid without the darkest and lightest
 *   shades; ties to the first candidate): deterministic, well-spread hues and lightnesses.
 *   Once the grid is used up (thousands of labels) the remaining labels get distinct colours
 *   still, from a fixed walk through the 24-bit colours. */
#include "check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
  double L, a, b;
} lab_t;

static double srgb_to_linear(int c)
{
  const double x = c / 255.0;
  return x <= 0.04045 ? x / 12.92 : pow((x + 0.055) / 1.055, 2.4);
}

static double lab_curve(double t)
{
  const double d = 6.0 / 29.0;
  return t > d * d * d ? cbrt(t) : t / (3.0 * d * d) + 4.0 / 29.0;
}

static lab_t rgb_to_lab(const int rgb[3])
{
  const double r = srgb_to_linear(rgb[0]), g = srgb_to_linear(rgb[1]), b = srgb_to_linear(rgb[2]);
  const double X = 0.4124564 * r + 0.3575761 * g + 0.1804375 * b;
  const double Y = 0.2126729 * r + 0.7151522 * g + 0.0721750 * b;
  const double Z = 0.0193339 * r + 0.1191920 * g + 0.9503041 * b;
  const double fx = lab_curve(X / 0.95047), fy = lab_curve(Y), fz = lab_curve(Z / 1.08883);
  return (lab_t){116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

static double lab_distance(lab_t p, lab_t q)
{
  return sqrt((p.L - q.L) * (p.L - q.L) + (p.a - q.a) * (p.a - q.a) + (p.b - q.b) * (p.b - q.b));
}

double ck_delta_e(const int a[3], const int b[3]) { return lab_distance(rgb_to_lab(a), rgb_to_lab(b)); }

/* ---- choosing the colours ---- */

static const int BACKGROUND[3] = {255, 255, 255};

/* First pass: the table colours far enough from the background and the ones kept so far. */
static void keep_table_colours(ck_palette_t *p, lab_t *lab, const i2m_label_names_t *t)
{
  const lab_t bg = rgb_to_lab(BACKGROUND);
  for (int64_t i = 0; i < p->n; i++) {
    ck_label_colour_t *c = &p->c[i];
    const char *name = i2m_label_name(t, c->value);
    const int32_t colour = i2m_label_colour(t, c->value);
    if (name) snprintf(c->name, sizeof c->name, "%s", name);
    if (colour < 0) continue; /* (no table entry, or a name without a colour: a segmentation's) */
    c->table = CK_COLOUR_REPLACED;
    const int rgb[3] = {colour >> 16 & 255, colour >> 8 & 255, colour & 255};
    const lab_t x = rgb_to_lab(rgb);
    int ok = lab_distance(x, bg) >= CK_MIN_DELTA_E;
    for (int64_t j = 0; ok && j < i; j++)
      if (p->c[j].table == CK_COLOUR_TABLE && lab_distance(x, lab[j]) < CK_MIN_DELTA_E) ok = 0;
    if (!ok) continue;
    memcpy(c->rgb, rgb, sizeof c->rgb);
    c->table = CK_COLOUR_TABLE;
    lab[i] = x;
  }
}

#define GRID_LEVELS 16
#define GRID_SIZE (GRID_LEVELS * GRID_LEVELS * GRID_LEVELS)

static int packed(const int rgb[3]) { return rgb[0] << 16 | rgb[1] << 8 | rgb[2]; }

static int cmp_int(const void *a, const void *b)
{
  const int x = *(const int *)a, y = *(const int *)b;
  return (x > y) - (x < y);
}

/* Labels left once the candidates are used up: distinct colours from a walk through the
 * 24-bit colours by an odd stride (a permutation), skipping those already given. */
static i2m_err_t distinct_colours(ck_palette_t *p, int64_t first)
{
  int *used = NULL;
  int64_t nu = 0;
  I2M_CALL(i2m_malloc((size_t)p->n + 1, sizeof *used, &used));
  for (int64_t i = 0; i < p->n; i++)
    if (p->c[i].rgb[0] >= 0) used[nu++] = packed(p->c[i].rgb);
  used[nu++] = packed(BACKGROUND);
  qsort(used, (size_t)nu, sizeof *used, cmp_int);
  uint32_t k = 0;
  for (int64_t i = first; i < p->n; i++) {
    if (p->c[i].rgb[0] >= 0) continue;
    int x;
    do x = (int)((++k * 0x9E3779u) & 0xFFFFFFu); /* (past 2^24 labels colours must repeat) */
    while (k < 0x1000000u && bsearch(&x, used, (size_t)nu, sizeof *used, cmp_int));
    p->c[i].rgb[0] = x >> 16, p->c[i].rgb[1] = x >> 8 & 255, p->c[i].rgb[2] = x & 255;
  }
  i2m_free(&used);
  return I2M_OK;
}

/* Second pass: every label without a colour (rgb[0] < 0) gets the candidate farthest from
 * the background and every colour given. */
static i2m_err_t spread_colours(ck_palette_t *p, const lab_t *lab)
{
  lab_t *cand = NULL;
  int (*rgb)[3] = NULL;
  double *far = NULL;
  int nc = 0;
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, out, i2m_malloc(GRID_SIZE, sizeof *cand, &cand));
  I2M_CALL_GOTO(err, out, i2m_malloc(GRID_SIZE, sizeof *rgb, &rgb));
  I2M_CALL_GOTO(err, out, i2m_malloc(GRID_SIZE, sizeof *far, &far));
  const lab_t bg = rgb_to_lab(BACKGROUND);
  for (int q = 0; q < GRID_SIZE; q++) {
    const int c[3] = {q / (GRID_LEVELS * GRID_LEVELS) * 17, q / GRID_LEVELS % GRID_LEVELS * 17, q % GRID_LEVELS * 17};
    const lab_t x = rgb_to_lab(c);
    if (x.L < 20.0 || x.L > 95.0) continue; /* near black hides the outlines; near white, the shape */
    memcpy(rgb[nc], c, sizeof c);
    cand[nc] = x;
    far[nc] = lab_distance(x, bg);
    for (int64_t j = 0; j < p->n; j++)
      if (p->c[j].table == CK_COLOUR_TABLE) far[nc] = fmin(far[nc], lab_distance(x, lab[j]));
    nc++;
  }
  for (int64_t i = 0; i < p->n; i++) {
    if (p->c[i].rgb[0] >= 0) continue;
    int best = 0;
    for (int q = 1; q < nc; q++)
      if (far[q] > far[best]) best = q;
    if (!(far[best] > 0.0)) { /* every candidate given: distinct colours for the rest */
      err = distinct_colours(p, i);
      break;
    }
    memcpy(p->c[i].rgb, rgb[best], sizeof rgb[best]);
    for (int q = 0; q < nc; q++) far[q] = fmin(far[q], lab_distance(cand[q], cand[best]));
  }
out:
  i2m_free(&cand);
  i2m_free(&rgb);
  i2m_free(&far);
  return err;
}

i2m_err_t ck_palette_build(const i2m_label_names_t *table, const int64_t *values, int64_t n, ck_palette_t *p)
{
  lab_t *lab = NULL;
  memset(p, 0, sizeof *p);
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)n + 1, sizeof *p->c, &p->c));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)n + 1, sizeof *lab, &lab));
  p->n = n;
  for (int64_t i = 0; i < n; i++)
    p->c[i] = (ck_label_colour_t){.value = values[i], .rgb = {-1, -1, -1}, .table = CK_COLOUR_NONE};
  keep_table_colours(p, lab, table);
  I2M_CALL_GOTO(err, out, spread_colours(p, lab));
out:
  i2m_free(&lab);
  if (err != I2M_OK) ck_palette_free(p);
  return err;
}

const ck_label_colour_t *ck_palette_find(const ck_palette_t *p, int64_t value)
{
  int64_t lo = 0, hi = p->n; /* values are sorted */
  while (lo < hi) {
    const int64_t mid = lo + (hi - lo) / 2;
    if (p->c[mid].value < value)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo < p->n && p->c[lo].value == value ? &p->c[lo] : NULL;
}

void ck_palette_free(ck_palette_t *p)
{
  i2m_free(&p->c);
  p->n = 0;
}
