/* i2m-check: plots as plain SVG written by hand.
 *   dihedral_histogram.svg  the 1-degree dihedral angle histogram (log count axis), min and
 *                           max marked (as in the PI2M / hybrid papers' Fig. 5);
 *   cross_section.svg       the mesh cut by the plane normal to the grid's k axis through the
 *                           middle of the image (middle of the mesh's bounding box, world z,
 *                           without an image); each cut tetrahedron drawn as its section
 *                           polygon filled with its label's colour, from a 3D Slicer colour
 *                           table beside the image (<base>.ctbl) or a fixed palette. */
#include "check.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
  int64_t value;
  int r, g, b;
  char name[64];
} color_t;

typedef struct {
  color_t *c; /* owned */
  int n, cap;
} ctable_t;

/* Writes s as XML character data: the five special characters as entities, control bytes
 * dropped (a colour table's names are anybody's text). */
static void svg_text(FILE *f, const char *s)
{
  for (; *s; s++) {
    const unsigned char c = (unsigned char)*s;
    if (c == '<') fputs("&lt;", f);
    else if (c == '>') fputs("&gt;", f);
    else if (c == '&') fputs("&amp;", f);
    else if (c == '"') fputs("&quot;", f);
    else if (c == '\'') fputs("&apos;", f);
    else if (c >= 0x20 && c != 0x7f) fputc(c, f);
  }
}

static i2m_err_t plot_histogram(const char *path, const ck_quality_t *q)
{
  i2m_outfile_t out;
  I2M_CALL(i2m_outfile_open(&out, path, "w"));
  FILE *f = out.f;
  const double W = 900, H = 420, x0 = 70, y0 = 360, pw = 800, ph = 320;
  int64_t maxc = 1;
  for (int b = 0; b < CK_HIST_BINS; b++)
    if (q->dihedral_hist[b] > maxc) maxc = q->dihedral_hist[b];
  double top = ceil(log10((double)maxc + 1.0));
  if (top < 1) top = 1;
  fprintf(f, "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%g\" height=\"%g\" "
             "font-family=\"sans-serif\" font-size=\"12\">\n", W, H);
  fprintf(f, "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n");
  int64_t total = 0;
  for (int b = 0; b < CK_HIST_BINS; b++) total += q->dihedral_hist[b];
  fprintf(f, "<text x=\"%g\" y=\"20\" font-size=\"15\">Dihedral angles (1&#176; bins, %lld "
             "angles, log count axis)</text>\n", x0, (long long)total);
  for (int b = 0; b < CK_HIST_BINS; b++) {
    if (q->dihedral_hist[b] == 0) continue;
    double h = log10((double)q->dihedral_hist[b] + 1.0) / top * ph;
    fprintf(f, "<rect x=\"%.2f\" y=\"%.2f\" width=\"%.2f\" height=\"%.2f\" fill=\"#4a7ab5\"/>\n",
            x0 + b * pw / 180.0, y0 - h, pw / 180.0, h);
  }
  fprintf(f, "<line x1=\"%g\" y1=\"%g\" x2=\"%g\" y2=\"%g\" stroke=\"black\"/>\n", x0, y0, x0 + pw, y0);
  fprintf(f, "<line x1=\"%g\" y1=\"%g\" x2=\"%g\" y2=\"%g\" stroke=\"black\"/>\n", x0, y0, x0, y0 - ph);
  for (int d = 0; d <= 180; d += 20)
    fprintf(f, "<text x=\"%.1f\" y=\"%g\" text-anchor=\"middle\">%d</text>\n", x0 + d * pw / 180.0,
            y0 + 16, d);
  for (int e = 0; e <= (int)top; e++)
    fprintf(f, "<text x=\"%g\" y=\"%.1f\" text-anchor=\"end\">1e%d</text>\n", x0 - 6,
            y0 - e / top * ph + 4, e);
  fprintf(f, "<text x=\"%g\" y=\"%g\" text-anchor=\"middle\">dihedral angle (degrees)</text>\n",
          x0 + pw / 2, y0 + 36);
  const double mk[2] = {q->min_dihedral, q->max_dihedral};
  const char *nm[2] = {"min", "max"};
  for (int i = 0; i < 2; i++) {
    double x = x0 + mk[i] * pw / 180.0;
    fprintf(f, "<line x1=\"%.2f\" y1=\"%g\" x2=\"%.2f\" y2=\"%g\" stroke=\"#c0392b\" "
               "stroke-dasharray=\"4 3\"/>\n", x, y0, x, y0 - ph);
    fprintf(f, "<text x=\"%.2f\" y=\"%g\" fill=\"#c0392b\" text-anchor=\"%s\">%s %.2f&#176;</text>\n",
            x + (i ? -4 : 4), y0 - ph + 14 + 16 * i, i ? "end" : "start", nm[i], mk[i]);
  }
  fprintf(f, "</svg>\n");
  return i2m_outfile_commit(&out);
}

/* ---- colours ---- */
static void ctable_load(const char *image_path, ctable_t *t)
{
  memset(t, 0, sizeof *t);
  if (!image_path) return;
  char path[4096];
  snprintf(path, sizeof path, "%s", image_path);
  size_t n = strlen(path);
  if (n > 3 && strcmp(path + n - 3, ".gz") == 0) path[n - 3] = '\0';
  char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
  if (dot && (!slash || dot > slash)) *dot = '\0';
  if (strlen(path) + 6 >= sizeof path) return;
  strcat(path, ".ctbl");
  FILE *f = fopen(path, "r");
  if (!f) return;
  char line[512];
  while (fgets(line, sizeof line, f)) {
    long long v;
    int r, g, b, a;
    char name[64];
    if (line[0] == '#' || sscanf(line, "%lld %63s %d %d %d %d", &v, name, &r, &g, &b, &a) < 5)
      continue;
    if (t->n == t->cap) {
      t->cap = t->cap ? 2 * t->cap : 64;
      if (i2m_realloc((size_t)t->cap, sizeof *t->c, &t->c) != I2M_OK) break;
    }
    color_t *c = &t->c[t->n++];
    c->value = v;
    c->r = r & 255;
    c->g = g & 255;
    c->b = b & 255;
    snprintf(c->name, sizeof c->name, "%s", name);
  }
  fclose(f);
}

static const color_t *ctable_find(const ctable_t *t, int64_t v)
{
  for (int i = 0; i < t->n; i++)
    if (t->c[i].value == v) return &t->c[i];
  return NULL;
}

static void label_rgb(const ctable_t *t, int64_t v, int rgb[3])
{
  static const int pal[12][3] = {{228, 26, 28},  {55, 126, 184}, {77, 175, 74},  {152, 78, 163},
                                 {255, 127, 0},  {200, 200, 51}, {166, 86, 40},  {247, 129, 191},
                                 {102, 194, 165}, {141, 160, 203}, {231, 138, 195}, {166, 216, 84}};
  const color_t *c = ctable_find(t, v);
  if (c) {
    rgb[0] = c->r, rgb[1] = c->g, rgb[2] = c->b;
  } else {
    uint64_t h = (uint64_t)v * 0x9E3779B97F4A7C15ull;
    const int *p = pal[(h >> 40) % 12];
    rgb[0] = p[0], rgb[1] = p[1], rgb[2] = p[2];
  }
}

/* ---- cross-section ---- */

/* Section polygon of tet with vertex coordinates p[4] by the plane z = c; returns #points. */
static int cut_tet(const double *p[4], double c, double out[4][2])
{
  static const int E[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  int n = 0;
  for (int e = 0; e < 6; e++) {
    const double *a = p[E[e][0]], *b = p[E[e][1]];
    int sa = a[2] >= c, sb = b[2] >= c;
    if (sa == sb) continue;
    double t = (c - a[2]) / (b[2] - a[2]);
    out[n][0] = a[0] + t * (b[0] - a[0]);
    out[n][1] = a[1] + t * (b[1] - a[1]);
    n++;
  }
  if (n == 4) { /* order the quadrilateral around its centre */
    double cx = 0, cy = 0, ang[4];
    for (int i = 0; i < 4; i++) cx += out[i][0] / 4, cy += out[i][1] / 4;
    for (int i = 0; i < 4; i++) ang[i] = atan2(out[i][1] - cy, out[i][0] - cx);
    for (int i = 1; i < 4; i++)
      for (int j = i; j > 0 && ang[j] < ang[j - 1]; j--) {
        double t = ang[j];
        ang[j] = ang[j - 1];
        ang[j - 1] = t;
        for (int k = 0; k < 2; k++) {
          t = out[j][k];
          out[j][k] = out[j - 1][k];
          out[j - 1][k] = t;
        }
      }
  }
  return n;
}

static int cmp_i64p(const void *a, const void *b)
{
  int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
  return (x > y) - (x < y);
}

static void legend(FILE *f, const ctable_t *ct, int64_t *labs, int64_t n, double x, double y)
{
  qsort(labs, (size_t)n, sizeof *labs, cmp_i64p);
  int row = 0;
  for (int64_t i = 0; i < n && row < 70; i++) {
    if (i > 0 && labs[i] == labs[i - 1]) continue;
    int rgb[3];
    label_rgb(ct, labs[i], rgb);
    const color_t *c = ctable_find(ct, labs[i]);
    fprintf(f, "<rect x=\"%g\" y=\"%g\" width=\"12\" height=\"12\" fill=\"rgb(%d,%d,%d)\" "
               "stroke=\"black\" stroke-width=\"0.5\"/>\n", x, y + 16 * row, rgb[0], rgb[1], rgb[2]);
    fprintf(f, "<text x=\"%g\" y=\"%g\">%lld%s", x + 18, y + 16 * row + 11, (long long)labs[i], c ? " " : "");
    svg_text(f, c ? c->name : "");
    fprintf(f, "</text>\n");
    row++;
  }
}

static i2m_err_t plot_section(const char *path, const ck_mesh_t *m, const i2m_image_t *img,
                              const char *image_path)
{
  double *g = NULL, lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY}, zlo = INFINITY,
         zhi = -INFINITY;
  int64_t *labs = NULL, nl = 0;
  ctable_t ct;
  I2M_CALL(i2m_malloc((size_t)m->nv * 3, sizeof *g, &g));
  for (int64_t v = 0; v < m->nv; v++) {
    if (img)
      i2m_image_world_to_grid(img, m->xyz + 3 * v, g + 3 * v);
    else
      memcpy(g + 3 * v, m->xyz + 3 * v, 3 * sizeof *g);
    for (int a = 0; a < 2; a++) {
      lo[a] = fmin(lo[a], g[3 * v + a]);
      hi[a] = fmax(hi[a], g[3 * v + a]);
    }
    zlo = fmin(zlo, g[3 * v + 2]);
    zhi = fmax(zhi, g[3 * v + 2]);
  }
  double c = img ? 0.5 * (double)(img->n[2] - 1) * img->spacing[2] : 0.5 * (zlo + zhi);
  if (img)
    for (int a = 0; a < 2; a++) {
      lo[a] = -0.5 * img->spacing[a];
      hi[a] = ((double)img->n[a] - 0.5) * img->spacing[a];
    }
  double ext = fmax(hi[0] - lo[0], hi[1] - lo[1]);
  double sc = ext > 0 ? 800.0 / ext : 1.0, W = (hi[0] - lo[0]) * sc + 340, H = fmax((hi[1] - lo[1]) * sc, 400) + 60;
  i2m_err_t err = i2m_malloc((size_t)m->nt, sizeof *labs, &labs);
  i2m_outfile_t out;
  if (err == I2M_OK) err = i2m_outfile_open(&out, path, "w");
  if (err != I2M_OK) {
    i2m_free(&g);
    i2m_free(&labs);
    return err;
  }
  FILE *f = out.f;
  ctable_load(image_path, &ct);
  fprintf(f, "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" "
             "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%%\" height=\"100%%\" "
             "fill=\"white\"/>\n", W, H);
  fprintf(f, "<text x=\"10\" y=\"20\" font-size=\"15\">Cross-section at %s = %.3f mm</text>\n",
          img ? "grid k axis" : "world z", c);
  fprintf(f, "<g stroke=\"#222\" stroke-width=\"0.15\" stroke-linejoin=\"round\">\n");
  for (int64_t t = 0; t < m->nt; t++) {
    const double *p[4];
    double poly[4][2];
    for (int i = 0; i < 4; i++) p[i] = g + 3 * m->tet[4 * t + i];
    int n = cut_tet(p, c, poly);
    if (n < 3) continue;
    int rgb[3];
    label_rgb(&ct, m->tet_label[t], rgb);
    labs[nl++] = m->tet_label[t];
    fprintf(f, "<polygon fill=\"rgb(%d,%d,%d)\" points=\"", rgb[0], rgb[1], rgb[2]);
    for (int i = 0; i < n; i++)
      fprintf(f, "%.2f,%.2f ", 10 + (poly[i][0] - lo[0]) * sc, 40 + (hi[1] - poly[i][1]) * sc);
    fprintf(f, "\"/>\n");
  }
  fprintf(f, "</g>\n");
  legend(f, &ct, labs, nl, (hi[0] - lo[0]) * sc + 30, 40);
  fprintf(f, "</svg>\n");
  err = i2m_outfile_commit(&out);
  i2m_free(&ct.c);
  i2m_free(&g);
  i2m_free(&labs);
  return err;
}

i2m_err_t ck_plot(const char *dir, const ck_mesh_t *m, const ck_quality_t *q,
                  const i2m_image_t *img, const char *image_path)
{
  char path[4096];
  snprintf(path, sizeof path, "%s/dihedral_histogram.svg", dir);
  I2M_CALL(plot_histogram(path, q));
  snprintf(path, sizeof path, "%s/cross_section.svg", dir);
  return plot_section(path, m, img, image_path);
}
