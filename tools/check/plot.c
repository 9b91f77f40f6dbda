/* i2m-check: plots as plain SVG written by hand.
 *   dihedral_histogram.svg  the 1-degree dihedral angle histogram (log count axis), min and
 *                           max marked (as in the PI2M / hybrid papers' Fig. 5);
 *   cross_section_<a>.svg   the mesh cut by a plane normal to world axis a (x, y, z: the
 *                           file's coordinates, mm); by default the three mid-planes of the
 *                           image's world box (of the mesh's box without an image).  Each cut
 *                           tetrahedron is drawn as its section polygon, filled with its
 *                           label's colour (palette.c: every two labels told apart), grouped
 *                           by label (<g class="label" data-label="V" fill="#rrggbb">); axes
 *                           with ticks in world mm, a scale bar, and a legend (value, name
 *                           from the colour table, colour). */
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


/* ---- slices ---- */

static const char AXIS_NAME[3] = {'x', 'y', 'z'};
/* The picture's horizontal and vertical world axes for a plane normal to each axis. */
static const int AXIS_U[3] = {1, 0, 0}, AXIS_V[3] = {2, 2, 1};

int ck_slice_parse(const char *text, ck_slice_t *s, char *why, size_t cap)
{
  memset(s, 0, sizeof *s);
  s->text = text;
  const char *ax = strchr("xyz", text[0]);
  if (text[0] == '\0' || !ax || text[1] != '=') {
    snprintf(why, cap, "bad --slice value '%s': expected x=, y= or z= followed by a fraction 0..1 "
             "(z=0.5) or a world coordinate in mm (z=40mm)", text);
    return 0;
  }
  s->axis = (int)(ax - "xyz");
  char *end;
  errno = 0;
  s->value = strtod(text + 2, &end);
  s->in_mm = strcmp(end, "mm") == 0;
  if (end == text + 2 || (*end && !s->in_mm) || !isfinite(s->value) || errno == ERANGE) {
    snprintf(why, cap, "bad --slice value '%s': after '%c=' a number: a fraction 0..1 (%c=0.5) or "
             "a world coordinate in mm (%c=40mm)", text, text[0], text[0], text[0]);
    return 0;
  }
  if (!s->in_mm && !(s->value >= 0.0 && s->value <= 1.0)) {
    snprintf(why, cap, "bad --slice value '%s': a fraction of the range must lie in 0..1 (for a "
             "coordinate in mm write %c=%gmm)", text, text[0], s->value);
    return 0;
  }
  return 1;
}

/* Bounding box of the finite vertices (lo > hi when there is none). */
static void mesh_box(const ck_mesh_t *m, double lo[3], double hi[3])
{
  for (int a = 0; a < 3; a++) lo[a] = INFINITY, hi[a] = -INFINITY;
  for (int64_t v = 0; v < m->nv; v++) {
    const double *x = m->xyz + 3 * v;
    if (!isfinite(x[0]) || !isfinite(x[1]) || !isfinite(x[2])) continue;
    for (int a = 0; a < 3; a++) {
      lo[a] = fmin(lo[a], x[a]);
      hi[a] = fmax(hi[a], x[a]);
    }
  }
}

/* The frame the slices refer to: the image's world box, or the mesh's box. */
static void frame_box(const ck_mesh_t *m, const i2m_image_t *img, double lo[3], double hi[3])
{
  if (img)
    i2m_image_world_bounds(img, lo, hi);
  else
    mesh_box(m, lo, hi);
}

static const char *frame_name(const i2m_image_t *img) { return img ? "the image's" : "the mesh's"; }

i2m_err_t ck_slice_check(const ck_mesh_t *m, const i2m_image_t *img, const ck_slice_t *s, int n)
{
  double lo[3], hi[3];
  frame_box(m, img, lo, hi);
  for (int i = 0; i < n; i++) {
    const int a = s[i].axis;
    if (!s[i].in_mm || !(lo[a] <= hi[a])) continue;
    I2M_CHECK(s[i].value >= lo[a] && s[i].value <= hi[a], I2M_ERR_ARG,
              "--slice %s lies outside %s world %c range %.3f .. %.3f mm", s[i].text, frame_name(img),
              AXIS_NAME[a], lo[a], hi[a]);
  }
  return I2M_OK;
}

/* ---- the cut ---- */

/* One tetrahedron's section polygon (3 or 4 points, picture coordinates u, v in mm). */
typedef struct {
  int64_t label, tet;
  int n;
  double p[4][2];
} cut_t;

/* Section polygon of the tet with vertex coordinates p[4] by the plane x[axis] = c; returns
 * the number of points (a quadrilateral is ordered around its centre). */
static int cut_tet(const double *p[4], int axis, double c, double out[4][2])
{
  static const int E[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  const int u = AXIS_U[axis], v = AXIS_V[axis];
  int n = 0;
  for (int e = 0; e < 6; e++) {
    const double *a = p[E[e][0]], *b = p[E[e][1]];
    int sa = a[axis] >= c, sb = b[axis] >= c;
    if (sa == sb) continue;
    double t = (c - a[axis]) / (b[axis] - a[axis]);
    out[n][0] = a[u] + t * (b[u] - a[u]);
    out[n][1] = a[v] + t * (b[v] - a[v]);
    n++;
  }
  if (n == 4) {
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

static int cmp_cut(const void *a, const void *b)
{
  const cut_t *x = a, *y = b;
  if (x->label != y->label) return (x->label > y->label) - (x->label < y->label);
  return (x->tet > y->tet) - (x->tet < y->tet);
}

/* The section polygons of every tet the plane meets, by label then tet. */
static i2m_err_t cut_mesh(const ck_mesh_t *m, int axis, double c, cut_t **out, int64_t *nout)
{
  int64_t n = 0, cap = 0;
  *out = NULL;
  for (int64_t t = 0; t < m->nt; t++) {
    const double *p[4];
    double poly[4][2];
    for (int i = 0; i < 4; i++) p[i] = m->xyz + 3 * m->tet[4 * t + i];
    const int k = cut_tet(p, axis, c, poly);
    if (k < 3) continue;
    if (n == cap) {
      cap = cap ? 2 * cap : 1024;
      i2m_err_t err = i2m_realloc((size_t)cap, sizeof **out, out);
      if (err != I2M_OK) {
        i2m_free(out);
        return err;
      }
    }
    cut_t *x = &(*out)[n++];
    x->label = m->tet_label[t];
    x->tet = t;
    x->n = k;
    memcpy(x->p, poly, sizeof poly);
  }
  if (n) qsort(*out, (size_t)n, sizeof **out, cmp_cut);
  *nout = n;
  return I2M_OK;
}

/* ---- drawing ---- */

/* Where the picture goes: world (u, v) in mm -> pixels, v upwards. */
typedef struct {
  int axis, u, v;      /* the plane's normal; the horizontal and vertical world axes */
  double c;            /* the plane: world coordinate along axis, mm */
  double lo[2], hi[2]; /* world range shown along u and v, mm */
  double sc;           /* pixels per mm */
  double x0, y0;       /* pixels of the top left corner (lo[0], hi[1]) */
  double pw, ph;       /* plot size in pixels */
} view_t;

static double px(const view_t *w, double u) { return w->x0 + (u - w->lo[0]) * w->sc; }
static double py(const view_t *w, double v) { return w->y0 + (w->hi[1] - v) * w->sc; }

/* 1, 2 or 5 times a power of ten: the smallest >= x (largest <= x when !up). */
static double nice_step(double x, int up)
{
  if (!(x > 0) || !isfinite(x)) return 1.0;
  const double p = pow(10.0, floor(log10(x)));
  static const double m[4] = {1, 2, 5, 10};
  if (up) {
    for (int i = 0; i < 4; i++)
      if (m[i] * p >= x * (1 - 1e-12)) return m[i] * p;
    return 10 * p;
  }
  for (int i = 3; i >= 0; i--)
    if (m[i] * p <= x * (1 + 1e-12)) return m[i] * p;
  return p;
}

static int step_decimals(double step)
{
  const int d = (int)-floor(log10(step) + 1e-9);
  return d > 0 ? d : 0;
}

static void draw_ticks(FILE *f, const view_t *w, int which)
{
  const double lo = w->lo[which], hi = w->hi[which];
  const double step = nice_step((hi - lo) / 8.0, 1);
  const int dec = step_decimals(step);
  for (double k = ceil(lo / step - 1e-9); k * step <= hi + 1e-9 * step; k++) {
    const double t = k * step, shown = fabs(t) < 0.5 * step ? 0.0 : t; /* never "-0" */
    if (which == 0) {
      const double x = px(w, t), y = w->y0 + w->ph;
      fprintf(f, "<line x1=\"%.2f\" y1=\"%.2f\" x2=\"%.2f\" y2=\"%.2f\" stroke=\"black\"/>\n", x, y, x, y + 5);
      fprintf(f, "<text x=\"%.2f\" y=\"%.2f\" text-anchor=\"middle\">%.*f</text>\n", x, y + 18, dec, shown);
    } else {
      const double y = py(w, t);
      fprintf(f, "<line x1=\"%.2f\" y1=\"%.2f\" x2=\"%.2f\" y2=\"%.2f\" stroke=\"black\"/>\n", w->x0 - 5, y, w->x0,
              y);
      fprintf(f, "<text x=\"%.2f\" y=\"%.2f\" text-anchor=\"end\">%.*f</text>\n", w->x0 - 8, y + 4, dec, shown);
    }
  }
}

/* The plot's frame, ticks in world mm, axis names, and a scale bar below. */
static void draw_axes(FILE *f, const view_t *w)
{
  fprintf(f, "<g id=\"axes\" fill=\"black\">\n");
  fprintf(f, "<rect x=\"%.2f\" y=\"%.2f\" width=\"%.2f\" height=\"%.2f\" fill=\"none\" stroke=\"black\"/>\n",
          w->x0, w->y0, w->pw, w->ph);
  draw_ticks(f, w, 0);
  draw_ticks(f, w, 1);
  fprintf(f, "<text x=\"%.2f\" y=\"%.2f\" text-anchor=\"middle\">%c (mm, world)</text>\n", w->x0 + w->pw / 2,
          w->y0 + w->ph + 36, AXIS_NAME[w->u]);
  fprintf(f, "<text transform=\"translate(%.2f %.2f) rotate(-90)\" text-anchor=\"middle\">%c (mm, world)</text>\n",
          w->x0 - 52, w->y0 + w->ph / 2, AXIS_NAME[w->v]);
  const double len = nice_step((w->hi[0] - w->lo[0]) / 4.0, 0), y = w->y0 + w->ph + 58;
  fprintf(f, "<g id=\"scalebar\" data-mm=\"%g\">\n<path fill=\"none\" stroke=\"black\" stroke-width=\"2\" "
             "d=\"M %.2f %.2f v 6 H %.2f v -6\"/>\n", len, w->x0, y - 6, w->x0 + len * w->sc);
  fprintf(f, "<text x=\"%.2f\" y=\"%.2f\">%g mm</text>\n</g>\n</g>\n", w->x0 + len * w->sc + 8, y + 4, len);
}

/* The polygons, one group per label (one fill each). */
static void draw_cuts(FILE *f, const view_t *w, const cut_t *cut, int64_t n, const ck_palette_t *pal)
{
  fprintf(f, "<g id=\"mesh\" stroke=\"#222\" stroke-width=\"0.15\" stroke-linejoin=\"round\">\n");
  for (int64_t i = 0; i < n; i++) {
    if (i == 0 || cut[i].label != cut[i - 1].label) {
      const ck_label_colour_t *c = ck_palette_find(pal, cut[i].label);
      fprintf(f, "%s<g class=\"label\" data-label=\"%lld\" fill=\"#%02x%02x%02x\">\n", i ? "</g>\n" : "",
              (long long)cut[i].label, c->rgb[0], c->rgb[1], c->rgb[2]);
    }
    fprintf(f, "<polygon points=\"");
    for (int k = 0; k < cut[i].n; k++)
      fprintf(f, "%.2f,%.2f ", px(w, cut[i].p[k][0]), py(w, cut[i].p[k][1]));
    fprintf(f, "\"/>\n");
  }
  fprintf(f, "%s</g>\n", n ? "</g>\n" : "");
}

#define LEGEND_ROW 16
#define LEGEND_CHAR 7.0 /* pixels per character of a 12-pixel sans-serif font, about */
#define LEGEND_FOOTNOTE_WIDTH 270

/* Rows of the legend's columns for a plot ph pixels high. */
static int legend_rows(double ph) { return ph / LEGEND_ROW > 20 ? (int)(ph / LEGEND_ROW) : 20; }

/* Value, name (from the colour table) and colour of each label of the picture; a '*' marks a
 * table colour replaced (too close to another label's or the background). */
static void draw_legend(FILE *f, const cut_t *cut, int64_t n, const ck_palette_t *pal, double x, double y, int rows,
                        double column)
{
  int row = 0, replaced = 0;
  fprintf(f, "<g id=\"legend\">\n<text x=\"%.2f\" y=\"%.2f\" font-weight=\"bold\">label</text>\n", x, y - 8);
  for (int64_t i = 0; i < n; i++) {
    if (i > 0 && cut[i].label == cut[i - 1].label) continue;
    const ck_label_colour_t *c = ck_palette_find(pal, cut[i].label);
    const double cx = x + (row / rows) * column, cy = y + (row % rows) * LEGEND_ROW;
    fprintf(f, "<g class=\"legend-entry\" data-label=\"%lld\"><rect x=\"%.2f\" y=\"%.2f\" width=\"12\" height=\"12\" "
               "fill=\"#%02x%02x%02x\" stroke=\"black\" stroke-width=\"0.5\"/><text x=\"%.2f\" y=\"%.2f\">%lld",
            (long long)c->value, cx, cy, c->rgb[0], c->rgb[1], c->rgb[2], cx + 18, cy + 11, (long long)c->value);
    if (c->name[0]) fputc(' ', f);
    svg_text(f, c->name);
    fprintf(f, "%s</text></g>\n", c->table == CK_COLOUR_REPLACED ? " *" : "");
    replaced |= c->table == CK_COLOUR_REPLACED;
    row++;
  }
  if (replaced) {
    const double fy = y + ((row < rows ? row : rows) + 1) * LEGEND_ROW;
    fprintf(f, "<text x=\"%.2f\" y=\"%.2f\" font-size=\"10\">* the colour table's colour was too close to</text>\n",
            x, fy);
    fprintf(f, "<text x=\"%.2f\" y=\"%.2f\" font-size=\"10\">another label's or the background: replaced</text>\n",
            x, fy + 12);
  }
  fprintf(f, "</g>\n");
}

static int64_t distinct_labels(const cut_t *cut, int64_t n)
{
  int64_t k = 0;
  for (int64_t i = 0; i < n; i++) k += i == 0 || cut[i].label != cut[i - 1].label;
  return k;
}

/* Width of a legend column: its longest entry ("value name *") after the colour box. */
static double legend_column(const cut_t *cut, int64_t n, const ck_palette_t *pal)
{
  size_t longest = 4;
  for (int64_t i = 0; i < n; i++) {
    if (i > 0 && cut[i].label == cut[i - 1].label) continue;
    char num[32];
    const ck_label_colour_t *c = ck_palette_find(pal, cut[i].label);
    const size_t len = (size_t)snprintf(num, sizeof num, "%lld", (long long)c->value) + 1 + strlen(c->name) + 2;
    if (len > longest) longest = len;
  }
  return 18 + LEGEND_CHAR * (double)longest + 20;
}

/* A coordinate for the title: no "-0.000". */
static double tidy(double x) { return fabs(x) < 5e-4 ? 0.0 : x; }

/* The view of a slice: the frame's and the mesh's boxes along the picture's axes, 800 pixels
 * for the longer side (one scale for both: mm are square). */
static view_t slice_view(int axis, double c, const double flo[3], const double fhi[3], const double mlo[3],
                         const double mhi[3])
{
  view_t w = {.axis = axis, .u = AXIS_U[axis], .v = AXIS_V[axis], .c = c, .x0 = 80, .y0 = 64};
  const int ax[2] = {w.u, w.v};
  for (int i = 0; i < 2; i++) {
    w.lo[i] = fmin(flo[ax[i]], mlo[ax[i]]);
    w.hi[i] = fmax(fhi[ax[i]], mhi[ax[i]]);
    if (!(w.lo[i] < w.hi[i])) { /* a flat or empty box: 1 mm around it */
      const double mid = isfinite(w.lo[i]) ? 0.5 * (w.lo[i] + w.hi[i]) : 0.0;
      w.lo[i] = mid - 0.5, w.hi[i] = mid + 0.5;
    }
  }
  w.sc = 800.0 / fmax(w.hi[0] - w.lo[0], w.hi[1] - w.lo[1]);
  w.pw = (w.hi[0] - w.lo[0]) * w.sc;
  w.ph = (w.hi[1] - w.lo[1]) * w.sc;
  return w;
}

static void write_section(FILE *f, const view_t *w, const cut_t *cut, int64_t n, const ck_palette_t *pal,
                          const char *where)
{
  const int rows = legend_rows(w->ph);
  const int64_t nlab = distinct_labels(cut, n), cols = nlab ? (nlab + rows - 1) / rows : 1;
  const double column = legend_column(cut, n, pal);
  const double W = w->x0 + w->pw + 40 + fmax((double)cols * column, LEGEND_FOOTNOTE_WIDTH);
  const double H = fmax(w->y0 + w->ph + 80, w->y0 + (rows + 2) * LEGEND_ROW);
  fprintf(f, "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" font-family=\"sans-serif\" "
             "font-size=\"12\" data-axis=\"%c\" data-coordinate-mm=\"%.17g\">\n", W, H, AXIS_NAME[w->axis],
          w->c); /* (exact: a reader can classify the vertices as the cut did) */
  fprintf(f, "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n");
  fprintf(f, "<text x=\"10\" y=\"22\" font-size=\"15\">Cross-section %c = %.3f mm (world coordinates, the "
             "mesh file's)</text>\n", AXIS_NAME[w->axis], tidy(w->c));
  fprintf(f, "<text x=\"10\" y=\"42\">%s; %lld tetrahedra cut, %lld labels</text>\n", where, (long long)n,
          (long long)nlab);
  draw_cuts(f, w, cut, n, pal);
  if (n == 0)
    fprintf(f, "<text x=\"%.2f\" y=\"%.2f\" text-anchor=\"middle\">no tetrahedron meets this plane</text>\n",
            w->x0 + w->pw / 2, w->y0 + w->ph / 2);
  draw_axes(f, w);
  draw_legend(f, cut, n, pal, w->x0 + w->pw + 40, w->y0, rows, column);
  fprintf(f, "</svg>\n");
}

/* Context of all the slices of one run. */
typedef struct {
  const ck_mesh_t *m;
  const i2m_image_t *img;
  const ck_palette_t *pal;
  double flo[3], fhi[3], mlo[3], mhi[3]; /* the frame's and the mesh's boxes */
} section_ctx_t;

static i2m_err_t plot_section(const char *path, const section_ctx_t *x, const ck_slice_t *s)
{
  const int a = s->axis;
  const double c = s->in_mm ? s->value : x->flo[a] + s->value * (x->fhi[a] - x->flo[a]);
  char where[256];
  if (s->in_mm)
    snprintf(where, sizeof where, "plane normal to world %c, given in mm (%s); %s %c range %.3f .. %.3f mm",
             AXIS_NAME[a], s->text, frame_name(x->img), AXIS_NAME[a], x->flo[a], x->fhi[a]);
  else
    snprintf(where, sizeof where, "plane normal to world %c at %.3g of %s %c range %.3f .. %.3f mm", AXIS_NAME[a],
             s->value, frame_name(x->img), AXIS_NAME[a], x->flo[a], x->fhi[a]);
  cut_t *cut = NULL;
  int64_t n = 0;
  I2M_CALL(cut_mesh(x->m, a, c, &cut, &n));
  const view_t w = slice_view(a, c, x->flo, x->fhi, x->mlo, x->mhi);
  i2m_outfile_t out;
  i2m_err_t err = i2m_outfile_open(&out, path, "w");
  if (err == I2M_OK) {
    write_section(out.f, &w, cut, n, x->pal, where);
    err = i2m_outfile_commit(&out);
  }
  i2m_free(&cut);
  return err;
}

static int cmp_i64p(const void *a, const void *b)
{
  int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
  return (x > y) - (x < y);
}

/* Every distinct label of the mesh, increasing (one palette for all the pictures: a label has
 * the same colour in each). */
static i2m_err_t mesh_labels(const ck_mesh_t *m, int64_t **out, int64_t *nout)
{
  int64_t *v = NULL, n = 0;
  I2M_CALL(i2m_malloc((size_t)m->nt + 1, sizeof *v, &v));
  memcpy(v, m->tet_label, (size_t)m->nt * sizeof *v);
  qsort(v, (size_t)m->nt, sizeof *v, cmp_i64p);
  for (int64_t i = 0; i < m->nt; i++)
    if (i == 0 || v[i] != v[n - 1]) v[n++] = v[i];
  *out = v;
  *nout = n;
  return I2M_OK;
}

i2m_err_t ck_plot(const char *dir, const ck_mesh_t *m, const ck_quality_t *q, const i2m_image_t *img,
                  const ck_slice_t *slices, int nslices)
{
  char path[4096];
  snprintf(path, sizeof path, "%s/dihedral_histogram.svg", dir);
  I2M_CALL(plot_histogram(path, q));
  ck_slice_t mid[3];
  if (nslices == 0) {
    for (int a = 0; a < 3; a++) mid[a] = (ck_slice_t){.text = "mid-plane", .axis = a, .in_mm = 0, .value = 0.5};
    slices = mid;
    nslices = 3;
  }
  int64_t *labels = NULL, nlabels = 0;
  ck_palette_t pal = {0};
  section_ctx_t x = {.m = m, .img = img, .pal = &pal};
  frame_box(m, img, x.flo, x.fhi);
  mesh_box(m, x.mlo, x.mhi);
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, out, mesh_labels(m, &labels, &nlabels));
  I2M_CALL_GOTO(err, out, ck_palette_build(img ? img->names : NULL, labels, nlabels, &pal));
  for (int i = 0; i < nslices; i++) {
    int same = 0; /* earlier slices along this axis */
    for (int j = 0; j < i; j++) same += slices[j].axis == slices[i].axis;
    if (same)
      snprintf(path, sizeof path, "%s/cross_section_%c_%d.svg", dir, AXIS_NAME[slices[i].axis], same + 1);
    else
      snprintf(path, sizeof path, "%s/cross_section_%c.svg", dir, AXIS_NAME[slices[i].axis]);
    I2M_CALL_GOTO(err, out, plot_section(path, &x, &slices[i]));
  }
out:
  i2m_free(&labels);
  ck_palette_free(&pal);
  return err;
}
