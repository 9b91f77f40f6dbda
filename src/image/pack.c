/* Image layer: an image's description (geometry, label table, path, tissue names) as one flat
 * buffer and back, without its voxels, which travel as they are (img->vox, img->vox_hi).  The
 * dist layer broadcasts an image so: one rank reads and decodes the file, the others receive.
 * Host byte order and sizes: every process of a run is built alike.
 *
 * Layout, every field 8-byte aligned: "I2MIMG1" and a NUL; n[3]; spacing[3], origin[3],
 * dir[3][3]; file type, nlabels, has_hi (one int64 each); label_value[nlabels],
 * label_count[nlabels]; the path (a length, then its bytes); the names (a count, -1 for none,
 * then per name its value, colour and length, then its bytes). */
#include "image_impl.h"

#include <string.h>

#define PACK_MAGIC "I2MIMG1"

typedef struct {
  unsigned char *p; /* NULL while measuring */
  size_t len;
} packer_t;

static void put(packer_t *w, const void *x, size_t k)
{
  if (w->p) memcpy(w->p + w->len, x, k);
  w->len += (k + 7) & ~(size_t)7;
}

static void put_i64(packer_t *w, int64_t x) { put(w, &x, sizeof x); }

static void put_bytes(packer_t *w, const char *s, size_t k)
{
  put_i64(w, (int64_t)k);
  put(w, s, k);
}

static void pack_all(const i2m_image_t *img, packer_t *w)
{
  put(w, PACK_MAGIC, sizeof PACK_MAGIC);
  put(w, img->n, sizeof img->n);
  put(w, img->spacing, sizeof img->spacing);
  put(w, img->origin, sizeof img->origin);
  put(w, img->dir, sizeof img->dir);
  put_i64(w, (int64_t)img->file_type);
  put_i64(w, img->nlabels);
  put_i64(w, img->vox_hi != NULL);
  put(w, img->label_value, (size_t)img->nlabels * sizeof *img->label_value);
  put(w, img->label_count, (size_t)img->nlabels * sizeof *img->label_count);
  put_bytes(w, img->path, strlen(img->path));
  const i2m_label_names_t *nm = img->names;
  put_i64(w, nm ? nm->n : -1);
  for (int64_t i = 0; nm && i < nm->n; i++) {
    put_i64(w, nm->value[i]);
    put_i64(w, nm->colour[i]);
    put_bytes(w, nm->name[i], strlen(nm->name[i]));
  }
}

i2m_err_t i2m_image_pack_meta(const i2m_image_t *img, void **buf, size_t *len)
{
  packer_t w = {NULL, 0};
  pack_all(img, &w); /* (the size first) */
  *buf = NULL;
  I2M_CALL(i2m_calloc(w.len, 1, buf));
  w.p = *buf;
  w.len = 0;
  pack_all(img, &w);
  *len = w.len;
  return I2M_OK;
}

/* ---- unpacking, every read checked against the buffer's end ---- */

typedef struct {
  const unsigned char *p;
  size_t len, at;
} reader_t;

static i2m_err_t take(reader_t *r, void *x, size_t k)
{
  const size_t step = (k + 7) & ~(size_t)7;
  I2M_CHECK(step >= k && r->len - r->at >= step, I2M_ERR_INTERNAL, "an image description cut short");
  memcpy(x, r->p + r->at, k);
  r->at += step;
  return I2M_OK;
}

static i2m_err_t take_i64(reader_t *r, int64_t *x) { return take(r, x, sizeof *x); }

/* A length-prefixed string, NUL-terminated into *s (owned). */
static i2m_err_t take_string(reader_t *r, char **s, size_t *k)
{
  int64_t n = 0;
  I2M_CALL(take_i64(r, &n));
  I2M_CHECK(n >= 0 && (size_t)n <= r->len - r->at, I2M_ERR_INTERNAL, "an image description cut short");
  I2M_CALL(i2m_malloc((size_t)n + 1, 1, s));
  memcpy(*s, r->p + r->at, (size_t)n);
  (*s)[n] = '\0';
  r->at += ((size_t)n + 7) & ~(size_t)7;
  *k = (size_t)n;
  return I2M_OK;
}

static i2m_err_t unpack_names(reader_t *r, i2m_image_t *img)
{
  int64_t n = 0;
  I2M_CALL(take_i64(r, &n));
  if (n < 0) return I2M_OK;
  I2M_CALL(image_names_create(n, &img->names));
  for (int64_t i = 0; i < n; i++) {
    int64_t value = 0, colour = -1;
    char *name = NULL;
    size_t k;
    I2M_CALL(take_i64(r, &value));
    I2M_CALL(take_i64(r, &colour));
    I2M_CALL(take_string(r, &name, &k));
    const i2m_err_t err = image_names_add(img->names, value, name, k);
    i2m_free(&name);
    I2M_CALL(err);
    img->names->colour[i] = (int32_t)colour;
  }
  return I2M_OK;
}

static i2m_err_t unpack_rest(reader_t *r, i2m_image_t *img)
{
  int64_t type = 0, nlabels = 0, has_hi = 0;
  I2M_CALL(take(r, img->spacing, sizeof img->spacing));
  I2M_CALL(take(r, img->origin, sizeof img->origin));
  I2M_CALL(take(r, img->dir, sizeof img->dir));
  I2M_CALL(take_i64(r, &type));
  I2M_CALL(take_i64(r, &nlabels));
  I2M_CALL(take_i64(r, &has_hi));
  I2M_CHECK(nlabels >= 1 && nlabels <= 65536, I2M_ERR_INTERNAL, "an image description with %lld labels", (long long)nlabels);
  img->file_type = (i2m_scalar_t)type;
  img->nlabels = (int)nlabels;
  I2M_CALL(i2m_malloc((size_t)nlabels, sizeof *img->label_value, &img->label_value));
  I2M_CALL(i2m_malloc((size_t)nlabels, sizeof *img->label_count, &img->label_count));
  I2M_CALL(take(r, img->label_value, (size_t)nlabels * sizeof *img->label_value));
  I2M_CALL(take(r, img->label_count, (size_t)nlabels * sizeof *img->label_count));
  char *path = NULL;
  size_t k;
  I2M_CALL(take_string(r, &path, &k));
  i2m_free(&img->path);
  img->path = path;
  I2M_CALL(unpack_names(r, img));
  if (has_hi) I2M_CALL(image_add_high_plane(img));
  return I2M_OK;
}

i2m_err_t i2m_image_unpack_meta(const void *buf, size_t len, i2m_image_t **out)
{
  reader_t r = {buf, len, 0};
  char magic[sizeof PACK_MAGIC] = {0};
  int64_t n[3] = {0, 0, 0};
  *out = NULL;
  I2M_CALL(take(&r, magic, sizeof magic));
  I2M_CHECK(memcmp(magic, PACK_MAGIC, sizeof magic) == 0, I2M_ERR_INTERNAL, "not an image description");
  I2M_CALL(take(&r, n, sizeof n));
  i2m_image_t *img = NULL;
  I2M_CALL(image_alloc("", n, &img));
  const i2m_err_t err = unpack_rest(&r, img);
  if (err != I2M_OK) {
    i2m_image_destroy(&img);
    return err;
  }
  *out = img;
  return I2M_OK;
}
