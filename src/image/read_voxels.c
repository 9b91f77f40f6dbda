/* Image layer: streaming conversion of a file's voxels to label indices.  Each chunk the
 * stream hands out is converted in place of being copied: 8- and 16-bit voxels through a
 * table indexed by their bits, wider and floating-point ones through a small hash map from
 * value to index (with a one-entry cache for runs).  Indices are given in order of first
 * appearance, then renumbered so that index 0 is value 0 and the others increase with the
 * value.  Float voxels must hold integers; NaN, infinities and too many labels are errors. */
#include "image_impl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NO_INDEX 0xFFFFu
#define HASH_CAP ((size_t)1 << 17) /* > 2 * I2M_MAX_LABELS: the map never fills */

size_t image_scalar_size(i2m_scalar_t t)
{
  switch (t) {
  case I2M_SCALAR_INT8: case I2M_SCALAR_UINT8: return 1;
  case I2M_SCALAR_INT16: case I2M_SCALAR_UINT16: return 2;
  case I2M_SCALAR_INT32: case I2M_SCALAR_UINT32: case I2M_SCALAR_FLOAT32: return 4;
  case I2M_SCALAR_INT64: case I2M_SCALAR_UINT64: case I2M_SCALAR_FLOAT64: return 8;
  }
  return 0;
}

const char *image_describe_size(const int64_t n[3], i2m_scalar_t t, char *buf, size_t cap)
{
  int64_t size = (int64_t)image_scalar_size(t);
  int fits = n[0] > 0 && n[1] > 0 && n[2] > 0 && n[0] <= INT64_MAX / n[1] / n[2] / size;
  if (fits)
    snprintf(buf, cap, "%lldx%lldx%lld %s (%lld bytes)", (long long)n[0], (long long)n[1],
             (long long)n[2], i2m_scalar_name(t), (long long)(n[0] * n[1] * n[2] * size));
  else
    snprintf(buf, cap, "%lldx%lldx%lld %s (%.3g bytes)", (long long)n[0], (long long)n[1],
             (long long)n[2], i2m_scalar_name(t), (double)n[0] * (double)n[1] * (double)n[2] * (double)size);
  return buf;
}

i2m_err_t image_check_data_size(const image_stream_t *s, const int64_t n[3], i2m_scalar_t t)
{
  char what[160];
  image_describe_size(n, t, what, sizeof what);
  for (int a = 0; a < 3; a++)
    I2M_CHECK(n[a] >= 1, I2M_ERR_INPUT, "%s: header says %s: sizes must be positive", s->name, what);
  int64_t size = (int64_t)image_scalar_size(t);
  I2M_CHECK(n[0] <= INT64_MAX / n[1] / n[2] / size, I2M_ERR_INPUT,
            "%s: header says %s: absurd image size", s->name, what);
  int64_t bytes = n[0] * n[1] * n[2] * size;
  int64_t here = image_stream_tell(s);
  if (!s->gz) {
    int64_t left = s->file_size - here;
    I2M_CHECK(bytes <= left, I2M_ERR_INPUT,
              "%s: header says %s but the file holds only %lld bytes of data (truncated file?)",
              s->name, what, (long long)(left > 0 ? left : 0));
  } else { /* deflate cannot compress better than about 1032:1 */
    int64_t packed = s->file_size;
    I2M_CHECK(bytes / 1100 <= packed + 4096, I2M_ERR_INPUT,
              "%s: header says %s but a %lld-byte compressed file cannot hold that much data",
              s->name, what, (long long)packed);
  }
  return I2M_OK;
}

typedef struct {
  const image_voxels_t *vf;
  const char *name;    /* borrowed */
  i2m_image_t *img;    /* borrowed: vox[] is written */
  uint16_t *table;     /* owned: [256 or 65536] voxel bits -> index (8/16-bit types) */
  int64_t *hkey;       /* owned: [HASH_CAP] value -> index map: keys */
  uint16_t *hidx;      /* owned: [HASH_CAP] index, NO_INDEX for a free slot */
  int64_t *value;      /* owned: [I2M_MAX_LABELS] value of each index, first-seen order */
  int64_t *count;      /* owned: [I2M_MAX_LABELS] voxels of each index */
  int nidx, nnonzero;
  int64_t next;        /* linear index of the next voxel */
  int64_t last_value;  /* cache for runs (wider types) */
  uint16_t last_idx;
} conv_t;

static i2m_err_t bad_voxel(const conv_t *c, int64_t voxel, const char *what)
{
  const int64_t *n = c->img->n;
  return I2M_ERROR(I2M_ERR_INPUT, "%s: voxel (%lld,%lld,%lld) holds %s%s; a label image must hold "
                   "integer values", c->name, (long long)(voxel % n[0]),
                   (long long)(voxel / n[0] % n[1]), (long long)(voxel / n[0] / n[1]), what,
                   c->vf->scale ? " after scl_slope/scl_inter scaling" : "");
}

/* A double voxel value -> integer label, or an error naming the voxel. */
static i2m_err_t to_label(const conv_t *c, double d, int64_t voxel, int64_t *v)
{
  char what[64];
  if (isnan(d)) return bad_voxel(c, voxel, "NaN");
  if (isinf(d)) return bad_voxel(c, voxel, d > 0 ? "+infinity" : "-infinity");
  double r = nearbyint(d);
  if (c->vf->scale && fabs(d - r) <= 1e-6 * (fabs(r) > 1 ? fabs(r) : 1)) d = r; /* float scaling */
  if (d != r || !(d >= -9.2e18 && d <= 9.2e18)) {
    snprintf(what, sizeof what, d != r ? "the non-integer value %.17g" : "%.17g, out of range,", d);
    return bad_voxel(c, voxel, what);
  }
  *v = (int64_t)d;
  return I2M_OK;
}

/* Index of value v, given the next index if v is new. */
static i2m_err_t index_of(conv_t *c, int64_t v, uint16_t *idx)
{
  size_t h = (size_t)(((uint64_t)v * 0x9E3779B97F4A7C15ull) >> 40) & (HASH_CAP - 1);
  while (c->hidx[h] != NO_INDEX && c->hkey[h] != v) h = (h + 1) & (HASH_CAP - 1);
  if (c->hidx[h] == NO_INDEX) {
    if (v != 0) {
      I2M_CHECK(c->nnonzero < I2M_MAX_LABELS - 1, I2M_ERR_UNSUPPORTED,
                "%s: more than %d distinct label values (an intensity image rather than a label "
                "map?)", c->name, I2M_MAX_LABELS - 1);
      c->nnonzero++;
    }
    c->value[c->nidx] = v;
    c->count[c->nidx] = 0;
    c->hkey[h] = v;
    c->hidx[h] = (uint16_t)c->nidx++;
  }
  *idx = c->hidx[h];
  return I2M_OK;
}

/* 8/16-bit voxel bits not seen before: their value and index. */
static i2m_err_t learn_small(conv_t *c, uint32_t bits, int64_t voxel, uint16_t *idx)
{
  const image_voxels_t *vf = c->vf;
  int64_t raw = bits;
  if (vf->type == I2M_SCALAR_INT8 && bits >= 0x80u) raw = (int64_t)bits - 0x100;
  if (vf->type == I2M_SCALAR_INT16 && bits >= 0x8000u) raw = (int64_t)bits - 0x10000;
  int64_t v = raw;
  if (vf->scale) I2M_CALL(to_label(c, (double)raw * vf->slope + vf->inter, voxel, &v));
  I2M_CALL(index_of(c, v, idx));
  c->table[bits] = *idx;
  return I2M_OK;
}

static i2m_err_t conv_8(conv_t *c, const unsigned char *p, size_t k)
{
  uint16_t *tab = c->table;
  int64_t *cnt = c->count;
  for (size_t i = 0; i < k; i++) {
    uint16_t t = tab[p[i]];
    if (I2M_UNLIKELY(t == NO_INDEX)) I2M_CALL(learn_small(c, p[i], c->next + (int64_t)i, &t));
    I2M_CALL(image_store_index(c->img, c->next + (int64_t)i, t));
    cnt[t]++;
  }
  return I2M_OK;
}

static i2m_err_t conv_16(conv_t *c, const unsigned char *p, size_t k)
{
  uint16_t *tab = c->table;
  int64_t *cnt = c->count;
  int hi = c->vf->big_endian ? 0 : 1;
  for (size_t i = 0; i < k; i++) {
    uint32_t bits = (uint32_t)p[2 * i + hi] << 8 | p[2 * i + (1 - hi)];
    uint16_t t = tab[bits];
    if (I2M_UNLIKELY(t == NO_INDEX)) I2M_CALL(learn_small(c, bits, c->next + (int64_t)i, &t));
    I2M_CALL(image_store_index(c->img, c->next + (int64_t)i, t));
    cnt[t]++;
  }
  return I2M_OK;
}

/* One 4- or 8-byte voxel -> integer value. */
static i2m_err_t wide_value(const conv_t *c, const unsigned char *p, int64_t voxel, int64_t *v)
{
  const image_voxels_t *vf = c->vf;
  size_t size = image_scalar_size(vf->type);
  uint64_t u = 0;
  for (size_t b = 0; b < size; b++) u = u << 8 | p[vf->big_endian ? b : size - 1 - b];
  double d;
  switch (vf->type) {
  case I2M_SCALAR_INT32: *v = u >= 0x80000000u ? (int64_t)u - 0x100000000 : (int64_t)u; break;
  case I2M_SCALAR_UINT32: *v = (int64_t)u; break;
  case I2M_SCALAR_INT64: *v = u > (uint64_t)INT64_MAX ? -(int64_t)(~u) - 1 : (int64_t)u; break;
  case I2M_SCALAR_UINT64:
    if (u > (uint64_t)INT64_MAX) {
      char what[64];
      snprintf(what, sizeof what, "%llu, beyond the int64 range,", (unsigned long long)u);
      return bad_voxel(c, voxel, what);
    }
    *v = (int64_t)u;
    break;
  case I2M_SCALAR_FLOAT32: {
    uint32_t u32 = (uint32_t)u;
    float f;
    memcpy(&f, &u32, sizeof f);
    return to_label(c, vf->scale ? (double)f * vf->slope + vf->inter : (double)f, voxel, v);
  }
  case I2M_SCALAR_FLOAT64:
    memcpy(&d, &u, sizeof d);
    return to_label(c, vf->scale ? d * vf->slope + vf->inter : d, voxel, v);
  default: return I2M_ERROR(I2M_ERR_INTERNAL, "%s: wide_value on a small type", c->name);
  }
  if (vf->scale) I2M_CALL(to_label(c, (double)*v * vf->slope + vf->inter, voxel, v));
  return I2M_OK;
}

static i2m_err_t conv_wide(conv_t *c, const unsigned char *p, size_t k)
{
  size_t size = image_scalar_size(c->vf->type);
  for (size_t i = 0; i < k; i++) {
    int64_t v, voxel = c->next + (int64_t)i;
    I2M_CALL(wide_value(c, p + i * size, voxel, &v));
    if (v != c->last_value || c->last_idx == NO_INDEX) {
      I2M_CALL(index_of(c, v, &c->last_idx));
      c->last_value = v;
    }
    I2M_CALL(image_store_index(c->img, voxel, c->last_idx));
    c->count[c->last_idx]++;
  }
  return I2M_OK;
}

typedef struct {
  int64_t value;
  int idx;
} pair_t;

static int cmp_pair(const void *a, const void *b)
{
  int64_t x = ((const pair_t *)a)->value, y = ((const pair_t *)b)->value;
  if (x == 0 || y == 0) return (y == 0) - (x == 0); /* value 0 first */
  return (x > y) - (x < y);
}

/* First-seen indices -> final indices (0 = value 0, then increasing values). */
static i2m_err_t finish_labels(conv_t *c)
{
  i2m_image_t *img = c->img;
  pair_t *pairs = NULL;
  uint16_t *remap = NULL; /* [nidx] first-seen index -> final index */
  int has_zero = 0, identity = 1;
  I2M_CALL(i2m_malloc((size_t)c->nidx + 1, sizeof *pairs, &pairs));
  i2m_err_t err = i2m_malloc((size_t)c->nidx + 1, sizeof *remap, &remap);
  for (int k = 0; k < c->nidx; k++) {
    pairs[k].value = c->value[k];
    pairs[k].idx = k;
    has_zero |= c->value[k] == 0;
  }
  qsort(pairs, (size_t)c->nidx, sizeof *pairs, cmp_pair);
  img->nlabels = c->nnonzero + 1;
  if (err == I2M_OK) err = i2m_calloc((size_t)img->nlabels, sizeof(int64_t), &img->label_value);
  if (err == I2M_OK) err = i2m_calloc((size_t)img->nlabels, sizeof(int64_t), &img->label_count);
  for (int r = 0; err == I2M_OK && r < c->nidx; r++) {
    int fin = has_zero ? r : r + 1;
    remap[pairs[r].idx] = (uint16_t)fin;
    identity &= pairs[r].idx == fin;
    img->label_value[fin] = pairs[r].value;
    img->label_count[fin] = c->count[pairs[r].idx];
  }
  i2m_free(&pairs);
  if (err == I2M_OK && !identity) {
    int64_t nvox = img->n[0] * img->n[1] * img->n[2];
    for (int64_t i = 0; err == I2M_OK && i < nvox; i++) /* a high plane appears with the first index > 255 */
      err = image_store_index(img, i, remap[i2m_image_index(img, i)]);
  }
  i2m_free(&remap);
  return err;
}

static i2m_err_t conv_init(conv_t *c, const image_voxels_t *vf, image_stream_t *s, i2m_image_t *img)
{
  memset(c, 0, sizeof *c);
  c->vf = vf;
  c->name = s->name;
  c->img = img;
  c->last_idx = NO_INDEX;
  I2M_CALL(i2m_malloc(I2M_MAX_LABELS, sizeof *c->value, &c->value));
  I2M_CALL(i2m_malloc(I2M_MAX_LABELS, sizeof *c->count, &c->count));
  size_t size = image_scalar_size(vf->type);
  if (size <= 2) {
    size_t ntab = size == 1 ? 256 : 65536;
    I2M_CALL(i2m_malloc(ntab, sizeof *c->table, &c->table));
    memset(c->table, 0xFF, ntab * sizeof *c->table);
  }
  I2M_CALL(i2m_malloc(HASH_CAP, sizeof *c->hkey, &c->hkey));
  I2M_CALL(i2m_malloc(HASH_CAP, sizeof *c->hidx, &c->hidx));
  memset(c->hidx, 0xFF, HASH_CAP * sizeof *c->hidx);
  return I2M_OK;
}

static void conv_free(conv_t *c)
{
  i2m_free(&c->table);
  i2m_free(&c->hkey);
  i2m_free(&c->hidx);
  i2m_free(&c->value);
  i2m_free(&c->count);
}

static i2m_err_t short_data(const image_stream_t *s, const conv_t *c, size_t size, size_t avail)
{
  char what[160];
  long long got = (long long)(c->next * (int64_t)size + (int64_t)avail);
  image_describe_size(c->img->n, c->vf->type, what, sizeof what);
  if (s->gz)
    return I2M_ERROR(I2M_ERR_INPUT, "%s: header says %s but the gzip stream ends after %lld bytes%s",
                     s->name, what, got, s->z_truncated ? " (truncated gzip stream)" : "");
  return I2M_ERROR(I2M_ERR_INPUT, "%s: header says %s but the file ends after %lld bytes of data "
                   "(truncated file)", s->name, what, got);
}

i2m_err_t image_read_voxels(image_stream_t *s, const image_voxels_t *vf, i2m_image_t *img)
{
  conv_t c;
  i2m_err_t err = conv_init(&c, vf, s, img);
  size_t size = image_scalar_size(vf->type);
  int64_t total = img->n[0] * img->n[1] * img->n[2];
  i2m_progress_t pg; /* (large compressed images: inflating takes seconds) */
  i2m_progress_begin_total(&pg, "reading the image", "voxels", total);
  while (err == I2M_OK && c.next < total) {
    const unsigned char *p;
    size_t avail;
    I2M_CALL_GOTO(err, done, image_stream_peek(s, size, &p, &avail));
    if (avail < size) {
      err = short_data(s, &c, size, avail);
      break;
    }
    size_t k = avail / size;
    if ((int64_t)k > total - c.next) k = (size_t)(total - c.next);
    err = size == 1 ? conv_8(&c, p, k) : size == 2 ? conv_16(&c, p, k) : conv_wide(&c, p, k);
    image_stream_consume(s, k * size);
    c.next += (int64_t)k;
    i2m_progress_update(&pg, c.next);
  }
  i2m_progress_end(&pg, c.next);
  if (err == I2M_OK) err = finish_labels(&c);
  if (err == I2M_OK) img->file_type = vf->type;
done:
  conv_free(&c);
  return err;
}

i2m_err_t image_read_body(image_stream_t *s, image_stream_t *data, const image_voxels_t *vf, i2m_image_t *img)
{
  if (s->header_only) {
    i2m_free(&img->vox);
    return I2M_OK;
  }
  I2M_CALL(image_read_voxels(data, vf, img));
  return image_stream_finish(data);
}
