/* Image layer: i2m_image_read() and what the format readers share.  The format is found from
 * the first bytes (decompressed first when the file is gzip) and, failing that, from the
 * extension; the reader of that format then does the rest.  Also here: the geometry check
 * (finite positive spacing, orthonormal directions) and small header-text helpers. */
#define _XOPEN_SOURCE 700 /* realpath */
#include "image_impl.h"
#include "i2m/geometry.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

const char *i2m_image_format_name(i2m_image_format_t format)
{
  switch (format) {
  case I2M_IMAGE_FORMAT_NRRD: return "nrrd";
  case I2M_IMAGE_FORMAT_NIFTI: return "nifti";
  case I2M_IMAGE_FORMAT_METAIMAGE: return "metaimage";
  case I2M_IMAGE_FORMAT_INR: return "inr";
  case I2M_IMAGE_FORMAT_UNKNOWN: break;
  }
  return "unknown";
}

/* ---- header text helpers ---- */

static int lower(int ch) { return ch >= 'A' && ch <= 'Z' ? ch - 'A' + 'a' : ch; }
static int is_space(int ch) { return ch == ' ' || ch == '\t' || ch == '\r' || ch == '\n' || ch == '\v' || ch == '\f'; }

int image_streq(const char *a, const char *b)
{
  while (*a && lower((unsigned char)*a) == lower((unsigned char)*b)) a++, b++;
  return *a == '\0' && *b == '\0';
}

static int ends_with(const char *s, const char *suffix)
{
  size_t n = strlen(s), m = strlen(suffix);
  return n >= m && image_streq(s + n - m, suffix);
}

char *image_trim(char *s)
{
  while (is_space((unsigned char)*s)) s++;
  size_t n = strlen(s);
  while (n > 0 && is_space((unsigned char)s[n - 1])) s[--n] = '\0';
  return s;
}

int image_count_words(const char *text)
{
  int n = 0;
  for (const char *p = text; *p;) {
    while (is_space((unsigned char)*p)) p++;
    if (!*p) break;
    n++;
    while (*p && !is_space((unsigned char)*p)) p++;
  }
  return n;
}

int image_parse_ints(const char *text, int64_t *v, int n)
{
  const char *p = text;
  for (int i = 0; i < n; i++) {
    char *end;
    errno = 0;
    long long x = strtoll(p, &end, 10);
    if (end == p || errno == ERANGE || (*end && !is_space((unsigned char)*end))) return 0;
    v[i] = (int64_t)x;
    p = end;
  }
  while (is_space((unsigned char)*p)) p++;
  return *p == '\0';
}

int image_parse_doubles(const char *text, double *v, int n)
{
  const char *p = text;
  for (int i = 0; i < n; i++) {
    char *end;
    double x = strtod(p, &end);
    if (end == p || !isfinite(x) || (*end && !is_space((unsigned char)*end))) return 0;
    v[i] = x;
    p = end;
  }
  while (is_space((unsigned char)*p)) p++;
  return *p == '\0';
}

i2m_err_t image_sibling_path(const char *path, const char *file, int allow_external, char *out, size_t cap)
{
  const char *slash = strrchr(path, '/');
  size_t dir = file[0] == '/' || !slash ? 0 : (size_t)(slash - path) + 1;
  I2M_CHECK(dir + strlen(file) < cap, I2M_ERR_INPUT, "%s: data file name \"%.60s...\" is too long",
            path, file);
  memcpy(out, path, dir);
  strcpy(out + dir, file);
  if (allow_external) return I2M_OK;
  char header_dir[4096];
  I2M_CHECK(i2m_path_dir(path, header_dir, sizeof header_dir), I2M_ERR_INPUT, "%s: path too long", path);
  char *real_dir = realpath(header_dir, NULL), *real_data = realpath(out, NULL);
  bool inside = true;
  if (real_dir && real_data) { /* (a data file that is not there fails when it is opened) */
    const size_t k = strlen(real_dir);
    inside = strncmp(real_data, real_dir, k) == 0 && (real_data[k] == '/' || (k == 1 && real_dir[0] == '/'));
  }
  free(real_dir);
  free(real_data);
  I2M_CHECK(inside, I2M_ERR_INPUT,
            "%s: its data file \"%.200s\" lies outside the header's directory (refused; "
            "--allow-external-data reads it)", path, file);
  return I2M_OK;
}

/* ---- geometry ---- */

#define DEG_PER_RAD 57.29577951308232


static void normalise3(double a[3])
{
  double l = sqrt(i2m_dot3(a, a));
  for (int r = 0; r < 3; r++) a[r] /= l;
}

i2m_err_t image_check_spacing(const char *path, const char *field, int axis, double v)
{
  I2M_CHECK(isfinite(v) && v > 0, I2M_ERR_INPUT,
            "%s: %s of axis %d is %g: a spacing must be a positive number (a flipped axis belongs in "
            "the direction matrix)", path, field, axis, v);
  return I2M_OK;
}

#define SPACING_MIN_MM 1e-6
#define SPACING_MAX_MM 1e6
#define RANGE_VOXELS 0x1p32 /* (a double's 52 bits: 20 left below the voxel) */

i2m_err_t image_check_range(const i2m_image_t *img)
{
  double hmin = INFINITY, hmax = 0, far = 0, lo[3], hi[3];
  for (int a = 0; a < 3; a++) {
    hmin = fmin(hmin, img->spacing[a]);
    hmax = fmax(hmax, img->spacing[a]);
  }
  I2M_CHECK(hmin >= SPACING_MIN_MM && hmax <= SPACING_MAX_MM, I2M_ERR_UNSUPPORTED,
            "%s: voxel spacings of %g .. %g mm are outside what i2m meshes in double precision "
            "(%g .. %g mm)", img->path, hmin, hmax, SPACING_MIN_MM, SPACING_MAX_MM);
  i2m_image_world_bounds(img, lo, hi);
  for (int a = 0; a < 3; a++) far = fmax(far, fmax(fabs(lo[a]), fabs(hi[a])));
  I2M_CHECK(far <= hmin * RANGE_VOXELS, I2M_ERR_UNSUPPORTED,
            "%s: the image reaches %.4g mm from the world's origin, too far for its %g mm voxels to be "
            "meshed in double precision (at most %.4g mm: 2^32 voxels); move its origin closer",
            img->path, far, hmin, hmin * RANGE_VOXELS);
  return I2M_OK;
}

i2m_err_t image_set_geometry(i2m_image_t *img, double axis[3][3], const double origin[3])
{
  double u[3][3];
  for (int c = 0; c < 3; c++) {
    double len = sqrt(i2m_dot3(axis[c], axis[c]));
    I2M_CHECK(isfinite(len) && len > 0, I2M_ERR_INPUT,
              "%s: voxel spacing along axis %d is %g (it must be positive and finite)", img->path,
              c, len);
    I2M_CHECK(isfinite(origin[c]), I2M_ERR_INPUT, "%s: the origin is not finite", img->path);
    img->spacing[c] = len;
    for (int r = 0; r < 3; r++) u[c][r] = axis[c][r] / len;
  }
  double d01 = i2m_dot3(u[0], u[1]), d02 = i2m_dot3(u[0], u[2]), d12 = i2m_dot3(u[1], u[2]);
  double worst = fmax(fabs(d01), fmax(fabs(d02), fabs(d12)));
  I2M_CHECK(worst <= 1e-3, I2M_ERR_UNSUPPORTED,
            "%s: sheared voxel grids are not supported (the index axes make angles of %.4g, "
            "%.4g and %.4g degrees)", img->path, acos(fmin(1, fabs(d01))) * DEG_PER_RAD,
            acos(fmin(1, fabs(d02))) * DEG_PER_RAD, acos(fmin(1, fabs(d12))) * DEG_PER_RAD);
  if (worst > 0) { /* Gram-Schmidt: an exactly orthonormal frame is left untouched */
    for (int r = 0; r < 3; r++) u[1][r] -= d01 * u[0][r];
    normalise3(u[1]);
    double e0 = i2m_dot3(u[0], u[2]), e1 = i2m_dot3(u[1], u[2]);
    for (int r = 0; r < 3; r++) u[2][r] -= e0 * u[0][r] + e1 * u[1][r];
    normalise3(u[2]);
  }
  for (int r = 0; r < 3; r++) {
    img->origin[r] = origin[r] + 0.0; /* + 0.0 turns -0 into 0 */
    for (int c = 0; c < 3; c++) img->dir[r][c] = u[c][r] + 0.0;
  }
  return image_check_range(img);
}

/* ---- format detection and dispatch ---- */

/* Does the text start with "Key =" where Key is a MetaImage key (any word if !strict)? */
static int meta_key(const unsigned char *p, size_t n, int strict)
{
  static const char *keys[] = {"ObjectType", "NDims", "Comment", "ObjectSubType", "DimSize",
                               "ElementType", "HeaderSize", "BinaryData", "TransformType"};
  char word[32];
  size_t i = 0, k = 0;
  while (i < n && is_space(p[i])) i++;
  while (i < n && k < sizeof word - 1 && ((p[i] >= 'A' && p[i] <= 'Z') || (p[i] >= 'a' && p[i] <= 'z')))
    word[k++] = (char)p[i++];
  word[k] = '\0';
  while (i < n && (p[i] == ' ' || p[i] == '\t')) i++;
  if (i >= n || p[i] != '=' || k == 0) return 0;
  if (!strict) return 1;
  for (size_t j = 0; j < sizeof keys / sizeof keys[0]; j++)
    if (image_streq(word, keys[j])) return 1;
  return 0;
}

static i2m_image_format_t format_from_content(const unsigned char *p, size_t n)
{
  if (n >= 8 && memcmp(p, "NRRD000", 7) == 0) return I2M_IMAGE_FORMAT_NRRD;
  if (n >= 9 && memcmp(p, "NRRD00.01", 9) == 0) return I2M_IMAGE_FORMAT_NRRD;
  if (n >= 13 && memcmp(p, "#INRIMAGE-4#{", 13) == 0) return I2M_IMAGE_FORMAT_INR;
  if (n >= 348) {
    uint32_t le = p[0] | p[1] << 8 | p[2] << 16 | (uint32_t)p[3] << 24;
    uint32_t be = p[3] | p[2] << 8 | p[1] << 16 | (uint32_t)p[0] << 24;
    if ((le == 348 || be == 348) && (memcmp(p + 344, "n+1", 4) == 0 || memcmp(p + 344, "ni1", 4) == 0))
      return I2M_IMAGE_FORMAT_NIFTI;
  }
  if (meta_key(p, n, 1)) return I2M_IMAGE_FORMAT_METAIMAGE;
  return I2M_IMAGE_FORMAT_UNKNOWN;
}

static i2m_image_format_t format_from_extension(const char *path)
{
  if (ends_with(path, ".nrrd") || ends_with(path, ".nhdr")) return I2M_IMAGE_FORMAT_NRRD;
  if (ends_with(path, ".nii") || ends_with(path, ".nii.gz") || ends_with(path, ".hdr") ||
      ends_with(path, ".img"))
    return I2M_IMAGE_FORMAT_NIFTI;
  if (ends_with(path, ".mha") || ends_with(path, ".mhd")) return I2M_IMAGE_FORMAT_METAIMAGE;
  if (ends_with(path, ".inr") || ends_with(path, ".inr.gz")) return I2M_IMAGE_FORMAT_INR;
  return I2M_IMAGE_FORMAT_UNKNOWN;
}

/* x.img of a NIfTI-1 pair: read x.hdr instead (when it exists). */
static const char *pair_header(const char *path, char *buf, size_t cap)
{
  struct stat st;
  size_t n = strlen(path);
  if (!ends_with(path, ".img") || n >= cap) return path;
  memcpy(buf, path, n + 1);
  memcpy(buf + n - 4, path[n - 1] == 'G' ? ".HDR" : ".hdr", 4);
  return stat(buf, &st) == 0 ? buf : path;
}

static i2m_err_t read_detected(image_stream_t *s, const char *path, i2m_image_t **out,
                               i2m_image_format_t *fmt)
{
  const unsigned char *p;
  size_t n;
  int gz = 0;
  I2M_CALL(image_stream_peek(s, 2, &p, &n));
  if (n >= 2 && p[0] == 0x1f && p[1] == 0x8b) {
    I2M_CALL(image_stream_begin_gzip(s));
    gz = 1;
  }
  I2M_CALL(image_stream_peek(s, 352, &p, &n));
  *fmt = format_from_content(p, n);
  if (*fmt == I2M_IMAGE_FORMAT_UNKNOWN) {
    *fmt = format_from_extension(path);
    I2M_CHECK(*fmt != I2M_IMAGE_FORMAT_METAIMAGE || meta_key(p, n, 0), I2M_ERR_INPUT,
              "%s: not a MetaImage file (it does not start with a \"Key = Value\" line)", path);
  }
  I2M_CHECK(*fmt != I2M_IMAGE_FORMAT_UNKNOWN, I2M_ERR_UNSUPPORTED,
            "%s: unknown image format (the file is not NRRD, NIfTI-1, MetaImage or INR, and its "
            "extension is none of .nrrd .nhdr .nii .nii.gz .mha .mhd .inr .inr.gz)", path);
  I2M_CHECK(!gz || *fmt == I2M_IMAGE_FORMAT_NIFTI || *fmt == I2M_IMAGE_FORMAT_INR,
            I2M_ERR_UNSUPPORTED, "%s: a gzip-compressed %s file is not supported (use the "
            "format's own compression instead)", path, *fmt == I2M_IMAGE_FORMAT_NRRD ? "NRRD" : "MetaImage");
  switch (*fmt) {
  case I2M_IMAGE_FORMAT_NRRD: return image_read_nrrd(s, path, out);
  case I2M_IMAGE_FORMAT_NIFTI: return image_read_nifti(s, path, out);
  case I2M_IMAGE_FORMAT_METAIMAGE: return image_read_metaimage(s, path, out);
  case I2M_IMAGE_FORMAT_INR: return image_read_inr(s, path, out);
  case I2M_IMAGE_FORMAT_UNKNOWN: break;
  }
  return I2M_ERROR(I2M_ERR_INTERNAL, "%s: no reader", path);
}

i2m_err_t i2m_image_read_with(const char *path, const i2m_image_read_opts_t *opts, i2m_image_t **out,
                              i2m_image_format_t *format)
{
  image_stream_t s;
  i2m_image_format_t fmt = I2M_IMAGE_FORMAT_UNKNOWN;
  char hdr[4096];
  *out = NULL;
  if (format) *format = fmt;
  I2M_CHECK(path && path[0], I2M_ERR_ARG, "no image file name given");
  path = pair_header(path, hdr, sizeof hdr);
  i2m_err_t err = image_stream_open(path, &s);
  s.allow_external = opts && opts->allow_external_data;
  s.header_only = opts && opts->header_only;
  if (err == I2M_OK) err = read_detected(&s, path, out, &fmt);
  image_stream_close(&s);
  if (err == I2M_OK && !(opts && opts->header_only)) image_attach_ctbl(*out, path);
  if (err != I2M_OK) i2m_image_destroy(out);
  if (format) *format = fmt;
  return err;
}

i2m_err_t i2m_image_read_format(const char *path, i2m_image_t **out, i2m_image_format_t *format)
{
  return i2m_image_read_with(path, NULL, out, format);
}

i2m_err_t i2m_image_read(const char *path, i2m_image_t **out)
{
  return i2m_image_read_format(path, out, NULL);
}
