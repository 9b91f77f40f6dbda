/* Image layer: the label image object (creation from label values, destruction, frames).
 * Readers for the file formats live beside this file and end in image_finish_labels(). */
#include "image_impl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

const char *i2m_scalar_name(i2m_scalar_t t)
{
  static const char *names[] = {"int8",  "uint8",  "int16", "uint16",  "int32",
                                "uint32", "int64", "uint64", "float32", "float64"};
  return (unsigned)t < sizeof names / sizeof names[0] ? names[t] : "unknown";
}

void i2m_image_release_voxels(i2m_image_t *img)
{
  i2m_free(&img->vox);
  i2m_free(&img->vox_hi);
}

i2m_err_t image_add_high_plane(i2m_image_t *img)
{
  return i2m_calloc((size_t)(img->n[0] * img->n[1] * img->n[2]), 1, &img->vox_hi);
}

void i2m_image_destroy(i2m_image_t **img)
{
  if (!img || !*img) return;
  i2m_image_release_voxels(*img);
  i2m_free(&(*img)->label_value);
  i2m_free(&(*img)->label_count);
  i2m_free(&(*img)->path);
  i2m_label_names_destroy(&(*img)->names);
  i2m_free(img);
}

i2m_err_t image_alloc(const char *path, const int64_t n[3], i2m_image_t **out)
{
  i2m_image_t *img = NULL;
  *out = NULL;
  for (int a = 0; a < 3; a++)
    I2M_CHECK(n[a] >= 1, I2M_ERR_INPUT, "%s: image size %lld x %lld x %lld has an empty axis",
              path, (long long)n[0], (long long)n[1], (long long)n[2]);
  I2M_CHECK(n[0] <= INT64_MAX / n[1] / n[2] && n[0] * n[1] * n[2] <= ((int64_t)1 << 40),
            I2M_ERR_INPUT, "%s: image size %lld x %lld x %lld is too large", path,
            (long long)n[0], (long long)n[1], (long long)n[2]);
  I2M_CALL(i2m_calloc(1, sizeof *img, &img));
  size_t len = strlen(path) + 1;
  i2m_err_t err = i2m_malloc(len, 1, &img->path);
  if (err == I2M_OK) memcpy(img->path, path, len);
  if (err == I2M_OK) err = i2m_malloc((size_t)(n[0] * n[1] * n[2]), sizeof *img->vox, &img->vox);
  if (err != I2M_OK) {
    i2m_image_destroy(&img);
    return err;
  }
  for (int a = 0; a < 3; a++) {
    img->n[a] = n[a];
    img->spacing[a] = 1.0;
    img->origin[a] = 0.0;
    for (int b = 0; b < 3; b++) img->dir[a][b] = a == b ? 1.0 : 0.0;
  }
  img->file_type = I2M_SCALAR_INT64;
  *out = img;
  return I2M_OK;
}

/* Sorted distinct values -> label indices.  values[] is scanned once to collect the
 * distinct values (a hash set), which are sorted; background 0 gets index 0. */
typedef struct {
  int64_t *keys;
  uint16_t *idx;
  uint8_t *used;
  size_t cap;
} label_map_t;

static size_t map_slot(const label_map_t *m, int64_t v)
{
  uint64_t h = (uint64_t)v * 0x9E3779B97F4A7C15ull;
  size_t s = (size_t)(h >> 17) & (m->cap - 1);
  while (m->used[s] && m->keys[s] != v) s = (s + 1) & (m->cap - 1);
  return s;
}

static int cmp_i64(const void *a, const void *b)
{
  int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
  return (x > y) - (x < y);
}

i2m_err_t i2m_image_create_from_values(const int64_t n[3], const double spacing[3],
                                       const double origin[3], const double *dir,
                                       const int64_t *values, i2m_image_t **out)
{
  i2m_image_t *img = NULL;
  label_map_t m = {0};
  int64_t *distinct = NULL;
  i2m_err_t err = I2M_OK;
  *out = NULL;
  I2M_CALL(image_alloc("", n, &img));
  for (int a = 0; a < 3; a++) {
    I2M_CHECK_GOTO(spacing[a] > 0 && isfinite(spacing[a]), err, done, I2M_ERR_INPUT,
                   "image spacing %g along axis %d is not positive", spacing[a], a);
    img->spacing[a] = spacing[a];
    img->origin[a] = origin ? origin[a] : 0.0;
    if (dir)
      for (int b = 0; b < 3; b++) img->dir[a][b] = dir[3 * a + b];
  }
  I2M_CALL_GOTO(err, done, image_check_range(img));
  size_t nvox = (size_t)(n[0] * n[1] * n[2]);
  m.cap = 1024;
  I2M_CALL_GOTO(err, done, i2m_calloc(m.cap, sizeof *m.keys, &m.keys));
  I2M_CALL_GOTO(err, done, i2m_calloc(m.cap, sizeof *m.idx, &m.idx));
  I2M_CALL_GOTO(err, done, i2m_calloc(m.cap, sizeof *m.used, &m.used));
  size_t ndistinct = 0;
  for (size_t i = 0; i < nvox; i++) {
    size_t s = map_slot(&m, values[i]);
    if (m.used[s]) continue;
    I2M_CHECK_GOTO(ndistinct < I2M_MAX_LABELS - 1, err, done, I2M_ERR_UNSUPPORTED,
                   "image holds more than %d distinct label values", I2M_MAX_LABELS - 1);
    m.used[s] = 1;
    m.keys[s] = values[i];
    ndistinct++;
    if (2 * ndistinct > m.cap) { /* grow and rehash */
      label_map_t g = {0};
      g.cap = m.cap * 4;
      I2M_CALL_GOTO(err, done, i2m_calloc(g.cap, sizeof *g.keys, &g.keys));
      I2M_CALL_GOTO(err, done, i2m_calloc(g.cap, sizeof *g.idx, &g.idx));
      I2M_CALL_GOTO(err, done, i2m_calloc(g.cap, sizeof *g.used, &g.used));
      for (size_t k = 0; k < m.cap; k++)
        if (m.used[k]) {
          size_t t = map_slot(&g, m.keys[k]);
          g.used[t] = 1;
          g.keys[t] = m.keys[k];
        }
      i2m_free(&m.keys);
      i2m_free(&m.idx);
      i2m_free(&m.used);
      m = g;
    }
  }
  /* distinct values, 0 first, the rest increasing */
  I2M_CALL_GOTO(err, done, i2m_malloc(ndistinct + 1, sizeof *distinct, &distinct));
  size_t nd = 0;
  for (size_t k = 0; k < m.cap; k++)
    if (m.used[k] && m.keys[k] != 0) distinct[nd++] = m.keys[k];
  qsort(distinct, nd, sizeof *distinct, cmp_i64);
  img->nlabels = (int)nd + 1;
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)img->nlabels, sizeof(int64_t), &img->label_value));
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)img->nlabels, sizeof(int64_t), &img->label_count));
  for (size_t k = 0; k < nd; k++) {
    img->label_value[k + 1] = distinct[k];
    m.idx[map_slot(&m, distinct[k])] = (uint16_t)(k + 1);
  }
  for (size_t i = 0; i < nvox; i++) {
    uint16_t li = values[i] == 0 ? 0 : m.idx[map_slot(&m, values[i])];
    I2M_CALL_GOTO(err, done, image_store_index(img, (int64_t)i, li));
    img->label_count[li]++;
  }
  *out = img;
  img = NULL;
done:
  i2m_free(&m.keys);
  i2m_free(&m.idx);
  i2m_free(&m.used);
  i2m_free(&distinct);
  i2m_image_destroy(&img);
  return err;
}

void i2m_image_grid_to_world(const i2m_image_t *img, const double g[3], double w[3])
{
  for (int r = 0; r < 3; r++)
    w[r] = img->origin[r] + img->dir[r][0] * g[0] + img->dir[r][1] * g[1] + img->dir[r][2] * g[2];
}

void i2m_image_world_bounds_of(const i2m_image_t *img, const int64_t first[3], const int64_t last[3], double lo[3],
                               double hi[3])
{
  for (int a = 0; a < 3; a++) {
    lo[a] = INFINITY;
    hi[a] = -INFINITY;
  }
  for (int c = 0; c < 8; c++) { /* corners of the voxel block (outer faces) */
    double g[3], w[3];
    for (int a = 0; a < 3; a++) {
      bool top = (c >> a) & 1;
      g[a] = (top ? (double)last[a] + 0.5 : (double)first[a] - 0.5) * img->spacing[a];
    }
    i2m_image_grid_to_world(img, g, w);
    for (int a = 0; a < 3; a++) {
      lo[a] = fmin(lo[a], w[a]);
      hi[a] = fmax(hi[a], w[a]);
    }
  }
}

void i2m_image_mesh_shift(const i2m_image_t *img, double s[3])
{
  /* Mesh coordinates lie in the virtual box (the image block grown by its extent e on every
   * side) minus the origin, so within 2e of 0: |s| >= 8e leaves the factor of 2 that makes
   * fl(fl(p + s) - s) exact, with room to spare. */
  double lo[3], hi[3], e = 0;
  i2m_image_world_bounds(img, lo, hi);
  for (int a = 0; a < 3; a++) e = fmax(e, hi[a] - lo[a]);
  for (int a = 0; a < 3; a++) s[a] = fabs(img->origin[a]) >= 8.0 * e ? img->origin[a] : 0.0;
}

void i2m_image_world_bounds(const i2m_image_t *img, double lo[3], double hi[3])
{
  const int64_t first[3] = {0, 0, 0}, last[3] = {img->n[0] - 1, img->n[1] - 1, img->n[2] - 1};
  i2m_image_world_bounds_of(img, first, last, lo, hi);
}

int i2m_image_handedness(const i2m_image_t *img)
{
  const double(*D)[3] = img->dir;
  double det = D[0][0] * (D[1][1] * D[2][2] - D[1][2] * D[2][1]) -
               D[0][1] * (D[1][0] * D[2][2] - D[1][2] * D[2][0]) +
               D[0][2] * (D[1][0] * D[2][1] - D[1][1] * D[2][0]);
  return det < 0 ? -1 : 1;
}
