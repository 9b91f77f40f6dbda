/* Image layer: the Inrimage reader (.inr, .inr.gz; the format of CGAL's 3D image examples).
 * The header is text in blocks of 256 bytes: "#INRIMAGE-4#{", then KEY=VALUE lines (XDIM,
 * YDIM, ZDIM, VDIM, TYPE, PIXSIZE, CPU, VX, VY, VZ, optional XO/YO/ZO or TX/TY/TZ), padded
 * with newlines and closed by "##}\n"; the voxels follow.  Identity directions. */
#include "image_impl.h"

#include <string.h>

#define INR_BLOCK 256
#define INR_MAX_HEADER (64 * INR_BLOCK)

typedef struct {
  char text[INR_MAX_HEADER + 1];
  int64_t n[4];
  double vx[3], o[3];
  char type[64];
  int64_t pixsize;
  int big;
} inr_t;

/* Reads 256-byte blocks until one ends with "##}\n". */
static i2m_err_t inr_read_header(image_stream_t *s, const char *path, inr_t *h, size_t *len)
{
  size_t got;
  *len = 0;
  do {
    I2M_CHECK(*len < INR_MAX_HEADER, I2M_ERR_INPUT, "%s: INR header without end (no \"##}\")", path);
    I2M_CALL(image_stream_read(s, h->text + *len, INR_BLOCK, &got));
    *len += got;
    I2M_CHECK(got == INR_BLOCK, I2M_ERR_INPUT, "%s: the %s ends inside the INR header%s", path,
              s->gz ? "gzip stream" : "file", s->z_truncated ? " (truncated gzip stream)" : "");
    if (*len == INR_BLOCK)
      I2M_CHECK(memcmp(h->text, "#INRIMAGE-4#{", 13) == 0, I2M_ERR_INPUT,
                "%s: not an INR file (it does not start with \"#INRIMAGE-4#{\")", path);
  } while (memcmp(h->text + *len - 4, "##}\n", 4) != 0);
  h->text[*len] = '\0';
  I2M_CHECK(strlen(h->text) == *len, I2M_ERR_INPUT, "%s: binary data inside the INR header", path);
  return I2M_OK;
}

static i2m_err_t inr_field(inr_t *h, const char *path, const char *key, const char *value)
{
  static const char *ints[] = {"XDIM", "YDIM", "ZDIM", "VDIM"};
  static const char *reals[] = {"VX", "VY", "VZ", "XO", "YO", "ZO", "TX", "TY", "TZ"};
  for (int i = 0; i < 4; i++)
    if (strcmp(key, ints[i]) == 0)
      return image_parse_ints(value, &h->n[i], 1) ? I2M_OK
             : I2M_ERROR(I2M_ERR_INPUT, "%s: bad %s=%s", path, key, value);
  for (int i = 0; i < 9; i++)
    if (strcmp(key, reals[i]) == 0) {
      double *dst = i < 3 ? &h->vx[i] : &h->o[i % 3];
      return image_parse_doubles(value, dst, 1) ? I2M_OK
             : I2M_ERROR(I2M_ERR_INPUT, "%s: bad %s=%s", path, key, value);
    }
  if (strcmp(key, "TYPE") == 0) {
    I2M_CHECK(strlen(value) < sizeof h->type, I2M_ERR_INPUT, "%s: bad TYPE", path);
    strcpy(h->type, value);
  } else if (strcmp(key, "PIXSIZE") == 0) {
    char bits[64];
    long long ps = 0;
    I2M_CHECK(sscanf(value, "%lld %63s", &ps, bits) == 2 && strcmp(bits, "bits") == 0,
              I2M_ERR_INPUT, "%s: bad PIXSIZE=%s", path, value);
    h->pixsize = ps;
  } else if (strcmp(key, "CPU") == 0) {
    h->big = strcmp(value, "sun") == 0 || strcmp(value, "sgi") == 0;
    I2M_CHECK(h->big || strcmp(value, "decm") == 0 || strcmp(value, "alpha") == 0 ||
              strcmp(value, "pc") == 0, I2M_ERR_INPUT, "%s: unknown CPU=%s", path, value);
  }
  return I2M_OK; /* SCALE, comments ("#..."), GEOMETRY, ... */
}

static i2m_err_t inr_type(const inr_t *h, const char *path, i2m_scalar_t *t)
{
  static const struct {
    const char *type;
    int64_t bits;
    i2m_scalar_t t;
  } types[] = {
      {"unsigned fixed", 8, I2M_SCALAR_UINT8},   {"unsigned fixed", 16, I2M_SCALAR_UINT16},
      {"unsigned fixed", 32, I2M_SCALAR_UINT32}, {"unsigned fixed", 64, I2M_SCALAR_UINT64},
      {"signed fixed", 8, I2M_SCALAR_INT8},      {"signed fixed", 16, I2M_SCALAR_INT16},
      {"signed fixed", 32, I2M_SCALAR_INT32},    {"signed fixed", 64, I2M_SCALAR_INT64},
      {"float", 32, I2M_SCALAR_FLOAT32},         {"float", 64, I2M_SCALAR_FLOAT64},
  };
  for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
    if (strcmp(h->type, types[i].type) == 0 && h->pixsize == types[i].bits) {
      *t = types[i].t;
      return I2M_OK;
    }
  return I2M_ERROR(I2M_ERR_UNSUPPORTED, "%s: unsupported voxel type TYPE=%s, PIXSIZE=%lld bits",
                   path, h->type[0] ? h->type : "(none)", (long long)h->pixsize);
}

static i2m_err_t inr_parse(inr_t *h, const char *path)
{
  char *save = strchr(h->text, '\n') + 1; /* past "#INRIMAGE-4#{" (the text ends in "\n") */
  h->n[3] = 1;
  h->vx[0] = h->vx[1] = h->vx[2] = 1;
  for (char *line = save; *line;) {
    char *nl = strchr(line, '\n');
    if (nl) *nl = '\0';
    char *eq = strchr(line, '=');
    if (line[0] != '#' && eq) {
      *eq = '\0';
      I2M_CALL(inr_field(h, path, image_trim(line), image_trim(eq + 1)));
    }
    if (!nl) break;
    line = nl + 1;
  }
  for (int a = 0; a < 3; a++)
    I2M_CHECK(h->n[a] >= 1, I2M_ERR_INPUT, "%s: image size XDIM=%lld YDIM=%lld ZDIM=%lld must be "
              "positive", path, (long long)h->n[0], (long long)h->n[1], (long long)h->n[2]);
  I2M_CHECK(h->n[3] == 1, I2M_ERR_UNSUPPORTED, "%s: VDIM=%lld: vector images are not supported",
            path, (long long)h->n[3]);
  return I2M_OK;
}

static i2m_err_t inr_read(inr_t *h, image_stream_t *s, const char *path, i2m_image_t **out)
{
  size_t len;
  double axis[3][3] = {{0}};
  image_voxels_t vf = {I2M_SCALAR_UINT8, 0, 0, 1.0, 0.0};
  I2M_CALL(inr_read_header(s, path, h, &len));
  I2M_CALL(inr_parse(h, path));
  I2M_CALL(inr_type(h, path, &vf.type));
  vf.big_endian = h->big;
  for (int c = 0; c < 3; c++) {
    static const char *const field[3] = {"VX", "VY", "VZ"};
    I2M_CALL(image_check_spacing(path, field[c], c, h->vx[c]));
    axis[c][c] = h->vx[c];
  }
  I2M_CALL(image_check_data_size(s, h->n, vf.type));
  I2M_CALL(image_alloc(path, h->n, out));
  I2M_CALL(image_set_geometry(*out, axis, h->o));
  return image_read_body(s, s, &vf, *out);
}

i2m_err_t image_read_inr(image_stream_t *s, const char *path, i2m_image_t **out)
{
  inr_t *h = NULL;
  *out = NULL;
  I2M_CALL(i2m_calloc(1, sizeof *h, &h));
  i2m_err_t err = inr_read(h, s, path, out);
  i2m_free(&h);
  if (err != I2M_OK) i2m_image_destroy(out);
  return err;
}
