/* Image layer: exact Euclidean distance transform with feature transform (separable, one
 * pass per axis; the lower envelope of parabolas of Felzenszwalb and Huttenlocher carrying
 * the argmin), the closest-interface-point oracle and segment bisection. */
#include "i2m/edt.h"
#include "i2m/geometry.h"

#include <stdbool.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

static bool is_boundary(const i2m_image_t *img, int64_t i, int64_t j, int64_t k)
{
  int l = i2m_image_label_voxel(img, i, j, k);
  return i2m_image_label_voxel(img, i - 1, j, k) != l || i2m_image_label_voxel(img, i + 1, j, k) != l ||
         i2m_image_label_voxel(img, i, j - 1, k) != l || i2m_image_label_voxel(img, i, j + 1, k) != l ||
         i2m_image_label_voxel(img, i, j, k - 1) != l || i2m_image_label_voxel(img, i, j, k + 1) != l;
}

/* is_boundary for a voxel off the image's border (image index idx; s1, s2 the strides of
 * axes 1 and 2): its six neighbours without bounds checks. */
static inline bool is_boundary_inner(const i2m_image_t *img, int64_t idx, int64_t s1, int64_t s2)
{
  int l = i2m_image_index(img, idx);
  return i2m_image_index(img, idx - 1) != l || i2m_image_index(img, idx + 1) != l ||
         i2m_image_index(img, idx - s1) != l || i2m_image_index(img, idx + s1) != l ||
         i2m_image_index(img, idx - s2) != l || i2m_image_index(img, idx + s2) != l;
}

/* Box K: boundary voxels lie within one voxel of the foreground, so the foreground's
 * bounding box grown by one voxel (clamped to the image) holds them all. */
static void boundary_box(const i2m_image_t *img, int64_t lo[3], int64_t hi[3])
{
  for (int a = 0; a < 3; a++) {
    lo[a] = img->n[a];
    hi[a] = -1;
  }
  for (int64_t k = 0; k < img->n[2]; k++)
    for (int64_t j = 0; j < img->n[1]; j++) {
      const int64_t row = (k * img->n[1] + j) * img->n[0];
      int64_t first = -1, last = -1;
      for (int64_t i = 0; i < img->n[0]; i++)
        if (i2m_image_index(img, row + i)) {
          if (first < 0) first = i;
          last = i;
        }
      if (first < 0) continue;
      int64_t ijk_lo[3] = {first, j, k}, ijk_hi[3] = {last, j, k};
      for (int a = 0; a < 3; a++) {
        if (ijk_lo[a] < lo[a]) lo[a] = ijk_lo[a];
        if (ijk_hi[a] > hi[a]) hi[a] = ijk_hi[a];
      }
    }
  for (int a = 0; a < 3; a++) {
    if (hi[a] < 0) { /* no foreground: empty box */
      lo[a] = 0;
      hi[a] = -1;
      continue;
    }
    lo[a] = lo[a] > 0 ? lo[a] - 1 : 0;
    hi[a] = hi[a] < img->n[a] - 1 ? hi[a] + 1 : img->n[a] - 1;
  }
}

/* One 1-D pass of the squared distance transform along a line of n voxels with spacing w:
 * f[q] is the squared distance carried in from earlier passes (INFINITY: no feature),
 * out_arg[x] receives the q minimising f[q] + (w (x - q))^2.  v, z, g: scratch of n, n+1
 * and n.  The parabola of q has its lift g[q] = f[q] + (w q)^2 computed once, and the
 * intersection that stops the pops is the new breakpoint (one division per test). */
static void envelope_1d(const double *f, int64_t n, double w, int64_t *v, double *z, double *g, int64_t *out_arg)
{
  int64_t k = -1;
  double w2 = w * w;
  for (int64_t q = 0; q < n; q++) {
    if (!isfinite(f[q])) continue;
    const double fq = f[q] + w2 * (double)q * (double)q;
    g[q] = fq;
    double s = -INFINITY;
    while (k >= 0) {
      int64_t p = v[k];
      s = (fq - g[p]) / (2.0 * w2 * (double)(q - p));
      if (s > z[k]) break;
      k--;
    }
    k++;
    v[k] = q;
    z[k] = k == 0 ? -INFINITY : s;
    z[k + 1] = INFINITY;
  }
  if (k < 0) {
    for (int64_t x = 0; x < n; x++) out_arg[x] = -1;
    return;
  }
  int64_t j = 0;
  for (int64_t x = 0; x < n; x++) {
    while (z[j + 1] < (double)x) j++;
    out_arg[x] = v[j];
  }
}

/* q = f / m for f < 2^31: a double reciprocal gives q within one, a correction step makes
 * it exact (integer division is the slowest instruction on this path). */
static inline uint32_t div_fast(uint32_t f, uint32_t m, double inv_m)
{
  uint32_t q = (uint32_t)((double)f * inv_m);
  if (q * m > f) q--;
  else if ((q + 1) * m <= f) q++;
  return q;
}

/* Coordinates of a box-linear index (the box holds < 2^31 voxels). */
static inline void box_coords(const i2m_edt_t *e, uint32_t f, uint32_t c[3])
{
  uint32_t m0 = (uint32_t)e->m[0], m1 = (uint32_t)e->m[1];
  uint32_t q = div_fast(f, m0, e->inv_m[0]);
  c[0] = f - q * m0;
  c[2] = div_fast(q, m1, e->inv_m[1]);
  c[1] = q - c[2] * m1;
}

/* First pass, along axis 0: each voxel's nearest boundary voxel on its own row, by a
 * forward and a backward sweep. */
static void edt_pass_rows(i2m_edt_t *e, int64_t row0, int64_t row1, i2m_progress_t *pg)
{
  const int64_t n = e->m[0];
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t row = row0; row < row1; row++) {
    if ((row & 255) == 255) i2m_progress_add(pg, 256 * n);
    int32_t *ft = e->ft + row * n;
    int64_t last = -1;
    for (int64_t i = 0; i < n; i++) {
      if (ft[i] >= 0) last = i;
      ft[i] = last < 0 ? -1 : (int32_t)(row * n + last);
    }
    last = -1;
    for (int64_t i = n - 1; i >= 0; i--) {
      bool feature = ft[i] == (int32_t)(row * n + i);
      if (feature) last = i;
      if (last >= 0 && (ft[i] < 0 || (last - i) < (i - (ft[i] - row * n)))) ft[i] = (int32_t)(row * n + last);
    }
  }
}

/* Passes along axes 1 and 2: each voxel takes the best feature among the line's voxels'
 * current features (lower envelope of parabolas).  The feature of voxel q of the line lies
 * in the same (ax = q) slab, so its distance is that of the components along the earlier
 * axes only, read off the index difference: along axis 1 the feature is on the voxel's own
 * row (the difference is the offset along axis 0); along axis 2 it is in the voxel's own
 * slice, whose in-slice index gives both offsets with one division. */
static i2m_err_t edt_pass(i2m_edt_t *e, int ax, int64_t line0, int64_t line1, i2m_progress_t *pg)
{
  const int64_t *m = e->m;
  int64_t stride = ax == 1 ? m[0] : m[0] * m[1];
  int64_t n = m[ax];
  const double *sp = e->img->spacing;
  double s0 = sp[0] * sp[0], s1 = sp[1] * sp[1];
  const uint32_t m0 = (uint32_t)m[0];
  int failed = 0;
  I2M_OMP(omp parallel reduction(| : failed))
  {
    double *f = malloc((size_t)n * sizeof *f), *z = malloc((size_t)(n + 1) * sizeof *z);
    double *g = malloc((size_t)n * sizeof *g);
    int64_t *v = malloc((size_t)n * sizeof *v), *arg = malloc((size_t)n * sizeof *arg);
    int32_t *feat = malloc((size_t)n * sizeof *feat);
    if (!f || !z || !g || !v || !arg || !feat) failed = 1;
    I2M_OMP(omp for schedule(dynamic, 64))
    for (int64_t line = line0; line < line1; line++) {
      if ((line & 63) == 63) i2m_progress_add(pg, 64 * n);
      if (failed) continue;
      /* line start: axis 1 lines are indexed by (i, k), axis 2 lines by (i, j) */
      int64_t base = ax == 1 ? (line % m[0]) + (line / m[0]) * m[0] * m[1] : line;
      const int64_t i0 = line % m[0], j0 = ax == 2 ? line / m[0] : 0;
      for (int64_t q = 0; q < n; q++) {
        const int64_t idx = base + q * stride;
        int32_t fq = e->ft[idx];
        feat[q] = fq;
        if (fq < 0) {
          f[q] = INFINITY;
          continue;
        }
        if (ax == 1) {
          const double d0 = (double)(fq - idx);
          f[q] = s0 * d0 * d0;
        } else {
          const uint32_t in_slice = (uint32_t)(fq - q * stride), fj = div_fast(in_slice, m0, e->inv_m[0]);
          const double d0 = (double)((int64_t)(in_slice - fj * m0) - i0), d1 = (double)((int64_t)fj - j0);
          f[q] = s0 * d0 * d0 + s1 * d1 * d1;
        }
      }
      envelope_1d(f, n, sp[ax], v, z, g, arg);
      for (int64_t x = 0; x < n; x++) e->ft[base + x * stride] = arg[x] < 0 ? -1 : feat[arg[x]];
    }
    free(f);
    free(z);
    free(g);
    free(v);
    free(arg);
    free(feat);
  }
  I2M_CHECK(!failed, I2M_ERR_MEMORY, "out of memory in the distance transform");
  return I2M_OK;
}

static int bits_for(uint64_t maxval)
{
  int b = 0;
  while (b < 64 && (maxval >> b) != 0) b++;
  return b;
}

/* Puts each voxel's label index above its feature index when both fit in 32 bits. */
static void pack_labels(i2m_edt_t *e, int64_t nbox, int64_t j0, int64_t j1)
{
  const i2m_image_t *img = e->img;
  int fbits = bits_for((uint64_t)nbox - 1), lbits = bits_for((uint64_t)img->nlabels - 1);
  if (fbits + lbits > 32) return;
  e->label_shift = fbits;
  e->feat_mask = fbits >= 32 ? UINT32_MAX : (1u << fbits) - 1;
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t k = 0; k < e->m[2]; k++)
    for (int64_t j = j0; j < j1; j++) {
      int64_t row = (k * e->m[1] + j) * e->m[0];
      for (int64_t i = 0; i < e->m[0]; i++) {
        uint32_t lab = (uint32_t)i2m_image_label_voxel(img, e->lo[0] + i, e->lo[1] + j, e->lo[2] + k);
        e->ft[row + i] = (int32_t)((uint32_t)e->ft[row + i] | (lbits ? lab << fbits : 0u));
      }
    }
  e->labels_packed = true;
}

/* World <-> voxel coordinates relative to K: u_k = (R^T (p - origin))_k / s_k + 1/2 - lo_k,
 * so that floor(u_k) is the voxel index along k minus lo_k (the mesher's voxel rule), and
 * back, p = origin + R diag(s) (u + lo - 1/2). */
static void set_voxel_maps(i2m_edt_t *e)
{
  const i2m_image_t *img = e->img;
  for (int k = 0; k < 3; k++) {
    double t = 0.5 - (double)e->lo[k];
    for (int r = 0; r < 3; r++) {
      e->w2k[k][r] = img->dir[r][k] / img->spacing[k];
      t -= e->w2k[k][r] * img->origin[r];
    }
    e->w2k[k][3] = t;
  }
  for (int r = 0; r < 3; r++) {
    double t = img->origin[r];
    for (int k = 0; k < 3; k++) {
      e->k2w[r][k] = img->dir[r][k] * img->spacing[k];
      t += e->k2w[r][k] * ((double)e->lo[k] - 0.5);
    }
    e->k2w[r][3] = t;
  }
}

/* Marks the boundary voxels of slices [k0, k1) (their own index, the others -1); their
 * number. */
static int64_t mark_boundary(i2m_edt_t *e, int64_t k0, int64_t k1, i2m_progress_t *pg)
{
  const i2m_image_t *img = e->img;
  int64_t nb = 0;
  I2M_OMP(omp parallel for reduction(+ : nb) schedule(static))
  for (int64_t k = k0; k < k1; k++)
    for (int64_t j = 0; j < e->m[1]; j++) {
      if (((k * e->m[1] + j) & 255) == 255) i2m_progress_add(pg, 256 * e->m[0]); /* (every 256 rows) */
      const int64_t gj = e->lo[1] + j, gk = e->lo[2] + k, s1 = img->n[0], s2 = img->n[0] * img->n[1];
      const bool inner_row = gj > 0 && gj < img->n[1] - 1 && gk > 0 && gk < img->n[2] - 1;
      for (int64_t i = 0; i < e->m[0]; i++) {
        const int64_t idx = (k * e->m[1] + j) * e->m[0] + i, gi = e->lo[0] + i;
        const bool b = inner_row && gi > 0 && gi < img->n[0] - 1 ? is_boundary_inner(img, (gk * img->n[1] + gj) * s1 + gi, s1, s2)
                                                                   : is_boundary(img, gi, gj, gk);
        e->ft[idx] = b ? (int32_t)idx : -1;
        nb += b;
      }
    }
  return nb;
}

/* Process q's part [*lo, *hi) of n items. */
static void share_range(const i2m_edt_share_t *sh, int q, int64_t n, int64_t *lo, int64_t *hi)
{
  const int P = sh ? sh->nparts : 1;
  *lo = n * q / P;
  *hi = n * (q + 1) / P;
}

/* Every process's part to every process, after agreeing on err: its slices (the first two
 * passes done on them), or with rows its rows of every slice (the third).  Every process makes
 * these two exchanges, also after an error (count and displ may then be NULL). */
static i2m_err_t exchange_parts(i2m_edt_t *e, const i2m_edt_share_t *sh, bool rows, i2m_err_t err, int64_t *count,
                                int64_t *displ)
{
  if (err != I2M_OK) return sh->exchange(sh->ctx, err, NULL, NULL, NULL, 0, 0);
  const int64_t slice = e->m[0] * e->m[1], unit = rows ? e->m[0] : slice;
  for (int q = 0; q < sh->nparts; q++) {
    int64_t lo, hi;
    share_range(sh, q, rows ? e->m[1] : e->m[2], &lo, &hi);
    displ[q] = lo * unit;
    count[q] = (hi - lo) * unit;
  }
  return sh->exchange(sh->ctx, I2M_OK, e->ft, count, displ, rows ? e->m[2] : 1, slice);
}

static int64_t count_boundary(const i2m_edt_t *e, int64_t nbox)
{
  int64_t nb = 0;
  I2M_OMP(omp parallel for reduction(+ : nb) schedule(static))
  for (int64_t idx = 0; idx < nbox; idx++) nb += i2m_edt_feature(e, idx) == (uint32_t)idx;
  return nb;
}

/* The passes over this process's part: slices for the first two (each line of axes 0 and 1
 * lies in one slice), rows of every slice for the third (each line of axis 2 is one (i, j)),
 * the labels packed on those rows; with the parts exchanged in between. */
static i2m_err_t edt_compute(i2m_edt_t *e, const i2m_edt_share_t *sh, i2m_err_t err, int64_t nbox)
{
  const int q = sh ? sh->part : 0;
  int64_t k0, k1, j0, j1, *count = NULL, *displ = NULL;
  share_range(sh, q, e->m[2], &k0, &k1);
  share_range(sh, q, e->m[1], &j0, &j1);
  if (err == I2M_OK && sh) err = i2m_malloc((size_t)sh->nparts, sizeof *count, &count);
  if (err == I2M_OK && sh) err = i2m_malloc((size_t)sh->nparts, sizeof *displ, &displ);
  i2m_progress_t pg; /* (four passes over the voxels of the box, this process's part of each) */
  i2m_progress_begin_total(&pg, "distance transform", "voxels", 4 * nbox);
  if (err == I2M_OK) {
    e->nboundary = mark_boundary(e, k0, k1, &pg);
    edt_pass_rows(e, k0 * e->m[1], k1 * e->m[1], &pg);
    err = edt_pass(e, 1, k0 * e->m[0], k1 * e->m[0], &pg);
  }
  if (sh) err = exchange_parts(e, sh, false, err, count, displ);
  if (err == I2M_OK) err = edt_pass(e, 2, j0 * e->m[0], j1 * e->m[0], &pg);
  if (err == I2M_OK) pack_labels(e, nbox, j0, j1);
  if (sh) err = exchange_parts(e, sh, true, err, count, displ);
  if (err == I2M_OK && sh) e->nboundary = count_boundary(e, nbox);
  i2m_progress_end(&pg, 4 * nbox);
  i2m_free(&count);
  i2m_free(&displ);
  return err;
}

i2m_err_t i2m_edt_create_shared(const i2m_image_t *img, const i2m_edt_share_t *share, i2m_edt_t **out)
{
  i2m_edt_t *e = NULL;
  *out = NULL;
  const i2m_edt_share_t *sh = share && share->nparts > 1 ? share : NULL;
  i2m_err_t err = i2m_calloc(1, sizeof *e, &e);
  if (err != I2M_OK && sh) { /* the others learn it in the two exchanges every process makes */
    err = exchange_parts(NULL, sh, false, err, NULL, NULL);
    return exchange_parts(NULL, sh, true, err, NULL, NULL);
  }
  I2M_CALL(err);
  e->img = img;
  e->feat_mask = UINT32_MAX;
  int64_t hi[3];
  boundary_box(img, e->lo, hi);
  for (int a = 0; a < 3; a++) {
    e->m[a] = hi[a] - e->lo[a] + 1;
    e->inv_m[a] = e->m[a] > 0 ? 1.0 / (double)e->m[a] : 0.0;
    e->inv_spacing[a] = 1.0 / img->spacing[a];
  }
  set_voxel_maps(e);
  int64_t nbox = e->m[0] * e->m[1] * e->m[2];
  if (nbox <= 0) { /* no foreground at all */
    *out = e;
    return I2M_OK;
  }
  if (nbox >= INT32_MAX) {
    i2m_free(&e);
    return I2M_ERROR(I2M_ERR_UNSUPPORTED, "%s: the labelled region spans %lld voxels; at most 2^31 are supported",
                     img->path, (long long)nbox);
  }
  err = i2m_realloc_large((size_t)nbox, sizeof(int32_t), &e->ft); /* (e->ft is NULL: a malloc) */
  err = edt_compute(e, sh, err, nbox);
  if (err != I2M_OK) i2m_edt_destroy(&e);
  *out = e;
  return err;
}

i2m_err_t i2m_edt_create(const i2m_image_t *img, i2m_edt_t **out) { return i2m_edt_create_shared(img, NULL, out); }

void i2m_edt_destroy(i2m_edt_t **e)
{
  if (!e || !*e) return;
  i2m_free(&(*e)->ft);
  i2m_free(e);
}

/* ---- queries, in voxel coordinates relative to K: u = grid / spacing + 1/2 - lo, so that
 * voxel v of K spans [v, v + 1) along each axis (the mesher's one voxel rule).  Outside K
 * every label is 0 (K holds the whole foreground). ---- */

static inline void affine3(const double A[3][4], const double x[3], double y[3])
{
  for (int k = 0; k < 3; k++) y[k] = A[k][0] * x[0] + A[k][1] * x[1] + A[k][2] * x[2] + A[k][3];
}

static inline void grid_to_k(const i2m_edt_t *e, const double g[3], double u[3])
{
  for (int a = 0; a < 3; a++) u[a] = g[a] * e->inv_spacing[a] + 0.5 - (double)e->lo[a];
}

static inline void k_to_grid(const i2m_edt_t *e, const double u[3], double g[3])
{
  for (int a = 0; a < 3; a++) g[a] = (u[a] + (double)e->lo[a] - 0.5) * e->img->spacing[a];
}

/* The voxel of K nearest to u (u clamped into K; NaN counts as below), its box coordinates c
 * and index; *inside tells whether u lies in it. */
static int64_t voxel_clamped(const i2m_edt_t *e, const double u[3], int64_t c[3], bool *inside)
{
  *inside = true;
  for (int k = 0; k < 3; k++) {
    if (!(u[k] >= 0.0)) { /* (NaN too) */
      c[k] = 0;
      *inside = false;
    } else if (u[k] >= (double)e->m[k]) {
      c[k] = e->m[k] - 1;
      *inside = false;
    } else {
      c[k] = (int64_t)u[k];
    }
  }
  return (c[2] * e->m[1] + c[1]) * e->m[0] + c[0];
}

/* The voxel of K (box coordinates c) that holds u; false outside K (or NaN), where every
 * label is 0. */
static inline bool voxel_k(const i2m_edt_t *e, const double u[3], int64_t c[3])
{
  bool inside;
  voxel_clamped(e, u, c, &inside);
  return inside;
}

static int label_k(const i2m_edt_t *e, const double u[3])
{
  int64_t c[3];
  if (!voxel_k(e, u, c)) return 0;
  return i2m_edt_label_voxel(e, e->lo[0] + c[0], e->lo[1] + c[1], e->lo[2] + c[2]);
}

int i2m_edt_label_at(const i2m_edt_t *e, const double g[3])
{
  double u[3];
  grid_to_k(e, g, u);
  return label_k(e, u);
}

int i2m_edt_label_at_world(const i2m_edt_t *e, const double w[3])
{
  double u[3];
  i2m_edt_world_to_k(e, w, u);
  return label_k(e, u);
}

bool i2m_edt_image_voxel_k(const i2m_edt_t *e, const double u[3], int64_t v[3])
{
  if (!voxel_k(e, u, v)) return false;
  for (int a = 0; a < 3; a++) v[a] += e->lo[a];
  return true;
}

/* A row of K's labels for i2m_components_build: the words' high bits when packed. */
static void k_row(const void *ctx, int64_t i0, int64_t j, int64_t k, int64_t n, uint16_t *out)
{
  const i2m_edt_t *e = ctx;
  if (e->labels_packed) {
    const int32_t *w = e->ft + ((k - e->lo[2]) * e->m[1] + (j - e->lo[1])) * e->m[0] + (i0 - e->lo[0]);
    for (int64_t i = 0; i < n; i++) out[i] = (uint16_t)((uint32_t)w[i] >> e->label_shift);
    return;
  }
  for (int64_t i = 0; i < n; i++) out[i] = (uint16_t)i2m_image_label_voxel(e->img, i0 + i, j, k);
}

i2m_err_t i2m_edt_components(const i2m_edt_t *e, i2m_components_t *c)
{
  return i2m_components_build(e->lo, e->m, k_row, e, c);
}

/* Label of box voxel idx (box-linear index, box coordinates c): its word's high bits when
 * the labels are packed (nearly always), else the image's voxel. */
static inline int box_label(const i2m_edt_t *e, int64_t idx, const int64_t c[3], bool packed)
{
  if (packed) return (int)((uint32_t)e->ft[idx] >> e->label_shift);
  return i2m_image_label_voxel(e->img, e->lo[0] + c[0], e->lo[1] + c[1], e->lo[2] + c[2]);
}

/* Label of the neighbour of box voxel f (box coordinates fb) at box-linear offset off, or 0
 * when that neighbour lies outside K (!within): from the next word when the labels are packed
 * (nearly always), else from the image at box coordinates nc. */
static inline int neighbour_label(const i2m_edt_t *e, uint32_t f, int64_t off, bool within, const int64_t nc[3],
                                  bool packed)
{
  if (!within) return 0;
  if (packed) return (int)((uint32_t)e->ft[(int64_t)f + off] >> e->label_shift);
  return i2m_image_label_voxel(e->img, e->lo[0] + nc[0], e->lo[1] + nc[1], e->lo[2] + nc[2]);
}

/* The box voxel a probe at u (in voxel vox of K, or vox < 0) starts from, with its box
 * coordinates in c when the labels must come from the image (or u lies outside K). */
static I2M_INLINE int64_t probe_voxel(const i2m_edt_t *e, const double u[3], int64_t vox, int64_t c[3], bool *inside,
                                      bool packed)
{
  *inside = vox >= 0;
  return *inside && packed ? vox : voxel_clamped(e, u, c, inside);
}

int i2m_edt_label_k(const i2m_edt_t *e, const double u[3], int64_t vox)
{
  if (e->nboundary == 0) return 0;
  int64_t c[3] = {0, 0, 0};
  bool inside;
  const int64_t idx = probe_voxel(e, u, vox, c, &inside, e->labels_packed);
  return inside ? box_label(e, idx, c, e->labels_packed) : 0;
}

/* The probe at u (in voxel vox of K, or vox < 0 when u lies outside K or is NaN): its label
 * (when @p label is not NULL) and, unless the feature voxel of its voxel (of its projection
 * on K, for u outside K) lies farther than sqrt(max_d2), the closest point zk on the faces
 * between that voxel and its differently labelled neighbours, with the pair.  Returns
 * INFINITY when zk was not computed.  One word gives the label and the feature; the distance
 * from u to the feature voxel bounds every face point's from below.  Inlined with packed =
 * e->labels_packed as a constant. */
static I2M_INLINE double probe_k_in(const i2m_edt_t *e, const double u[3], int64_t vox, double max_d2, int *label,
                                    double zk[3], int pair[2], bool packed)
{
  const double *s = e->img->spacing;
  const int64_t *m = e->m;
  int64_t c[3] = {0, 0, 0};
  bool inside;
  const int64_t idx = probe_voxel(e, u, vox, c, &inside, packed);
  if (label) *label = inside ? box_label(e, idx, c, packed) : 0;
  const uint32_t f = i2m_edt_feature(e, idx);
  uint32_t fb[3];
  box_coords(e, f, fb);
  double q0[3], box2 = 0; /* u clamped into the feature voxel */
  for (int k = 0; k < 3; k++) {
    double lo = (double)fb[k], hi = lo + 1.0;
    q0[k] = u[k] < lo ? lo : u[k] > hi ? hi : u[k];
    box2 += i2m_sq((u[k] - q0[k]) * s[k]);
  }
  if (!(box2 <= max_d2)) return INFINITY;
  const int64_t fc[3] = {fb[0], fb[1], fb[2]}, stride[3] = {1, m[0], m[0] * m[1]};
  const int lb = box_label(e, f, fc, packed);
  double best = INFINITY;
  for (int ax = 0; ax < 3; ax++)
    for (int dir = -1; dir <= 1; dir += 2) {
      const bool within = dir < 0 ? fb[ax] > 0 : (int64_t)fb[ax] + 1 < m[ax];
      int64_t nc[3] = {fc[0], fc[1], fc[2]};
      nc[ax] += dir;
      const int ln = neighbour_label(e, f, dir * stride[ax], within, nc, packed);
      if (ln == lb) continue;
      double q[3] = {q0[0], q0[1], q0[2]};
      q[ax] = (double)fb[ax] + (dir > 0 ? 1.0 : 0.0);
      const double d2 = i2m_sq((u[0] - q[0]) * s[0]) + i2m_sq((u[1] - q[1]) * s[1]) + i2m_sq((u[2] - q[2]) * s[2]);
      if (d2 < best) {
        best = d2;
        memcpy(zk, q, sizeof q);
        pair[0] = lb < ln ? lb : ln;
        pair[1] = lb < ln ? ln : lb;
      }
    }
  return best; /* (a feature voxel always has a differing neighbour) */
}

double i2m_edt_closest(const i2m_edt_t *e, const double p[3], double max_d2, double z[3], int pair[2])
{
  int tmp[2];
  if (!pair) pair = tmp;
  pair[0] = pair[1] = 0;
  if (e->nboundary == 0) {
    memcpy(z, p, 3 * sizeof *z);
    return INFINITY;
  }
  double u[3], zk[3] = {0, 0, 0};
  grid_to_k(e, p, u);
  const int64_t vox = i2m_edt_voxel_k(e, u);
  const double d2 = e->labels_packed ? probe_k_in(e, u, vox, max_d2, NULL, zk, pair, true)
                                     : probe_k_in(e, u, vox, max_d2, NULL, zk, pair, false);
  if (!(d2 < INFINITY)) return INFINITY;
  k_to_grid(e, zk, z);
  return i2m_dist2(p, z);
}

void i2m_edt_probe_world(const i2m_edt_t *e, const double p[3], double max_d2, i2m_edt_probe_t *out)
{
  double u[3];
  i2m_edt_world_to_k(e, p, u);
  i2m_edt_probe_k(e, p, u, i2m_edt_voxel_k(e, u), max_d2, out);
}

void i2m_edt_probe_k(const i2m_edt_t *e, const double p[3], const double u[3], int64_t vox, double max_d2,
                     i2m_edt_probe_t *out)
{
  out->label = 0;
  out->d2 = INFINITY;
  out->pair[0] = out->pair[1] = 0;
  if (e->nboundary == 0) return; /* no foreground: background everywhere */
  double zk[3] = {0, 0, 0};
  const double d2 = e->labels_packed ? probe_k_in(e, u, vox, max_d2, &out->label, zk, out->pair, true) /* (hot: inlined) */
                                     : probe_k_in(e, u, vox, max_d2, &out->label, zk, out->pair, false);
  if (!(d2 < INFINITY)) return;
  affine3(e->k2w, zk, out->z);
  out->d2 = i2m_dist2(p, out->z);
}

void i2m_edt_bisect(const i2m_edt_t *e, const double a[3], const double b[3], double tol, double x[3],
                    int *label_a, int *label_b)
{
  double p[3] = {a[0], a[1], a[2]}, q[3] = {b[0], b[1], b[2]};
  int la = i2m_edt_label_at_world(e, p), lb = i2m_edt_label_at_world(e, q);
  double tol2 = tol * tol;
  for (int it = 0; it < 200 && i2m_dist2(p, q) > tol2; it++) {
    double m[3] = {0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1]), 0.5 * (p[2] + q[2])};
    int lm = i2m_edt_label_at_world(e, m);
    if (lm != la) { /* keep the half next to a: the first change from a */
      memcpy(q, m, sizeof m);
      lb = lm;
    } else {
      memcpy(p, m, sizeof m);
    }
  }
  for (int k = 0; k < 3; k++) x[k] = 0.5 * (p[k] + q[k]);
  *label_a = la;
  *label_b = lb;
}
