/* Image layer: the NIfTI-1 reader.  Single files (.nii, .nii.gz: magic "n+1", voxels at
 * vox_offset) and header/image pairs (.hdr + .img: magic "ni1"); either byte order, found from
 * sizeof_hdr == 348.  Geometry: sform when sform_code > 0, else qform (quaternion, qfac from
 * pixdim[0]) when qform_code > 0, else pixdim scaling; NIfTI's RAS world is turned into LPS by
 * negating x and y.  scl_slope/scl_inter are applied when they change values. */
#include "image_impl.h"

#include <math.h>
#include <string.h>

#define NIFTI_HDR 348

typedef struct {
  const unsigned char *h; /* borrowed: the 348 header bytes */
  int big;                /* big-endian file */
} nifti_t;

/* The image file of a .hdr/.img pair. */
typedef struct {
  image_stream_t ds;
  char img_path[4096];
  char data_name[8400]; /* "<header> (image file <img>)", for messages */
} nifti_pair_t;

static uint32_t nifti_u32(const nifti_t *x, size_t off)
{
  const unsigned char *p = x->h + off;
  return x->big ? (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]
                : (uint32_t)p[3] << 24 | (uint32_t)p[2] << 16 | (uint32_t)p[1] << 8 | p[0];
}

static int nifti_i16(const nifti_t *x, size_t off)
{
  const unsigned char *p = x->h + off;
  unsigned u = x->big ? (unsigned)p[0] << 8 | p[1] : (unsigned)p[1] << 8 | p[0];
  return u >= 0x8000u ? (int)u - 0x10000 : (int)u;
}

static double nifti_f32(const nifti_t *x, size_t off)
{
  uint32_t u = nifti_u32(x, off);
  float f;
  memcpy(&f, &u, sizeof f);
  return f;
}

/* Header byte offsets (nifti1.h). */
enum {
  OFF_DIM = 40, OFF_DATATYPE = 70, OFF_BITPIX = 72, OFF_PIXDIM = 76, OFF_VOX_OFFSET = 108,
  OFF_SCL_SLOPE = 112, OFF_SCL_INTER = 116, OFF_QFORM_CODE = 252, OFF_SFORM_CODE = 254,
  OFF_QUATERN_B = 256, OFF_QOFFSET_X = 268, OFF_SROW_X = 280, OFF_MAGIC = 344
};

static i2m_err_t nifti_type(const nifti_t *x, const char *path, i2m_scalar_t *t)
{
  static const struct {
    int code;
    i2m_scalar_t t;
  } types[] = {{2, I2M_SCALAR_UINT8},    {4, I2M_SCALAR_INT16},    {8, I2M_SCALAR_INT32},
               {16, I2M_SCALAR_FLOAT32}, {64, I2M_SCALAR_FLOAT64}, {256, I2M_SCALAR_INT8},
               {512, I2M_SCALAR_UINT16}, {768, I2M_SCALAR_UINT32}, {1024, I2M_SCALAR_INT64},
               {1280, I2M_SCALAR_UINT64}};
  int code = nifti_i16(x, OFF_DATATYPE), bitpix = nifti_i16(x, OFF_BITPIX);
  for (size_t i = 0; i < sizeof types / sizeof types[0]; i++) {
    if (types[i].code != code) continue;
    *t = types[i].t;
    I2M_CHECK(bitpix == 8 * (int)image_scalar_size(*t), I2M_ERR_INPUT,
              "%s: bitpix %d does not match datatype %d (%s)", path, bitpix, code, i2m_scalar_name(*t));
    return I2M_OK;
  }
  return I2M_ERROR(I2M_ERR_UNSUPPORTED, "%s: NIfTI datatype %d is not supported (a label image "
                   "needs an integer or real scalar type)", path, code);
}

static i2m_err_t nifti_dims(const nifti_t *x, const char *path, int64_t n[3])
{
  int nd = nifti_i16(x, OFF_DIM);
  I2M_CHECK(nd >= 1 && nd <= 7, I2M_ERR_INPUT, "%s: bad dim[0] = %d (must be 1 to 7)", path, nd);
  I2M_CHECK(nd >= 3, I2M_ERR_UNSUPPORTED, "%s: not a 3-D image (dim[0] = %d)", path, nd);
  for (int a = 4; a <= nd; a++)
    I2M_CHECK(nifti_i16(x, OFF_DIM + 2 * a) == 1, I2M_ERR_UNSUPPORTED,
              "%s: not a 3-D image (dim[0] = %d and dim[%d] = %d: a time series or vector image)",
              path, nd, a, nifti_i16(x, OFF_DIM + 2 * a));
  for (int a = 0; a < 3; a++) {
    n[a] = nifti_i16(x, OFF_DIM + 2 * (a + 1));
    I2M_CHECK(n[a] >= 1, I2M_ERR_INPUT, "%s: dim[%d] = %lld (sizes must be positive)", path, a + 1,
              (long long)n[a]);
  }
  return I2M_OK;
}

/* qform: rotation from the quaternion (b,c,d), a = sqrt(1 - b^2 - c^2 - d^2). */
static void nifti_quatern(const nifti_t *x, double axis[3][3], double origin[3])
{
  double b = nifti_f32(x, OFF_QUATERN_B), c = nifti_f32(x, OFF_QUATERN_B + 4);
  double d = nifti_f32(x, OFF_QUATERN_B + 8), a = 1.0 - (b * b + c * c + d * d);
  if (a < 1e-7) { /* float rounding of a 180-degree rotation: renormalise (b,c,d) */
    double s = 1.0 / sqrt(b * b + c * c + d * d);
    b *= s, c *= s, d *= s, a = 0.0;
  } else {
    a = sqrt(a);
  }
  double R[3][3] = {{a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)},
                    {2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)},
                    {2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b}};
  double qfac = nifti_f32(x, OFF_PIXDIM) < 0 ? -1.0 : 1.0;
  for (int col = 0; col < 3; col++) {
    double step = nifti_f32(x, OFF_PIXDIM + 4 * (col + 1)) * (col == 2 ? qfac : 1.0);
    for (int r = 0; r < 3; r++) axis[col][r] = R[r][col] * step;
  }
  for (int r = 0; r < 3; r++) origin[r] = nifti_f32(x, OFF_QOFFSET_X + 4 * r);
}

/* World (RAS) axes and origin from sform, qform or pixdim, then converted to LPS. */
static i2m_err_t nifti_geometry(const nifti_t *x, const char *path, double axis[3][3], double origin[3])
{
  const bool sform = nifti_i16(x, OFF_SFORM_CODE) > 0;
  for (int c = 0; c < 3 && !sform; c++) /* (qform and pixdim scaling use pixdim[1..3]) */
    I2M_CALL(image_check_spacing(path, "pixdim", c, nifti_f32(x, OFF_PIXDIM + 4 * (c + 1))));
  if (sform) {
    for (int r = 0; r < 3; r++) {
      for (int c = 0; c < 3; c++) axis[c][r] = nifti_f32(x, OFF_SROW_X + 16 * r + 4 * c);
      origin[r] = nifti_f32(x, OFF_SROW_X + 16 * r + 12);
    }
  } else if (nifti_i16(x, OFF_QFORM_CODE) > 0) {
    nifti_quatern(x, axis, origin);
  } else { /* "method 1" (ANALYZE): scaling only, in NIfTI's RAS world as ITK reads it */
    for (int c = 0; c < 3; c++) {
      for (int r = 0; r < 3; r++) axis[c][r] = r == c ? nifti_f32(x, OFF_PIXDIM + 4 * (c + 1)) : 0;
      origin[c] = 0;
    }
  }
  for (int r = 0; r < 2; r++) { /* RAS -> LPS */
    origin[r] = -origin[r];
    for (int c = 0; c < 3; c++) axis[c][r] = -axis[c][r];
  }
  return I2M_OK;
}

/* Reads the header; *pair = 1 for a .hdr/.img pair. */
static i2m_err_t nifti_header(image_stream_t *s, const char *path, unsigned char h[NIFTI_HDR],
                              nifti_t *x, int *pair)
{
  size_t got;
  memset(h, 0, NIFTI_HDR);
  I2M_CALL(image_stream_read(s, h, NIFTI_HDR, &got));
  x->h = h;
  x->big = 0;
  uint32_t le = nifti_u32(x, 0);
  x->big = 1;
  uint32_t be = nifti_u32(x, 0);
  x->big = le != NIFTI_HDR;
  I2M_CHECK(le != 540 && be != 540, I2M_ERR_UNSUPPORTED, "%s: NIfTI-2 files are not supported "
            "(only NIfTI-1)", path);
  I2M_CHECK(got >= 4 && (le == NIFTI_HDR || be == NIFTI_HDR), I2M_ERR_INPUT,
            "%s: not a NIfTI-1 file (%s)%s", path, got < 4 ? "too short" : "sizeof_hdr is not 348",
            s->z_truncated ? " (truncated gzip stream)" : "");
  I2M_CHECK(got == NIFTI_HDR, I2M_ERR_INPUT, "%s: the %s ends inside the %d-byte NIfTI header "
            "(after %zu bytes)%s", path, s->gz ? "gzip stream" : "file", NIFTI_HDR, got,
            s->z_truncated ? " (truncated gzip stream)" : "");
  *pair = memcmp(h + OFF_MAGIC, "ni1", 4) == 0;
  I2M_CHECK(*pair || memcmp(h + OFF_MAGIC, "n+1", 4) == 0, I2M_ERR_UNSUPPORTED,
            "%s: no NIfTI-1 magic \"n+1\" or \"ni1\" (an ANALYZE 7.5 header?)", path);
  return I2M_OK;
}

/* Moves to the first voxel: in this file, or at vox_offset in the .img of a pair. */
static i2m_err_t nifti_position(image_stream_t *s, const nifti_t *x, const char *path, int pair,
                                nifti_pair_t *pf)
{
  double off = nifti_f32(x, OFF_VOX_OFFSET);
  I2M_CHECK(isfinite(off) && off >= 0 && off == floor(off) && off < 9e15, I2M_ERR_INPUT,
            "%s: bad vox_offset %g", path, off);
  if (!pair) { /* vox_offset 0 in a .nii: unset, the voxels follow the 4 extension bytes */
    int64_t got, skip = off == 0 ? 4 : (int64_t)off - NIFTI_HDR;
    I2M_CHECK(skip >= 0, I2M_ERR_INPUT, "%s: vox_offset %g lies inside the header", path, off);
    I2M_CALL(image_stream_skip(s, skip, &got));
    I2M_CHECK(got == skip, I2M_ERR_INPUT, "%s: vox_offset %g lies past the end of the %s", path,
              off, s->gz ? "gzip stream" : "file");
    return I2M_OK;
  }
  size_t n = strlen(path);
  I2M_CHECK(n >= 4 && n < sizeof pf->img_path && image_streq(path + n - 4, ".hdr"),
            I2M_ERR_UNSUPPORTED, "%s: a NIfTI-1 pair header (magic \"ni1\") must be named .hdr, "
            "beside its .img", path);
  memcpy(pf->img_path, path, n + 1);
  memcpy(pf->img_path + n - 4, path[n - 1] == 'R' ? ".IMG" : ".img", 4);
  i2m_err_t err = image_stream_open(pf->img_path, &pf->ds);
  if (err != I2M_OK) {
    char msg[600];
    snprintf(msg, sizeof msg, "%s", i2m_error_message());
    return I2M_ERROR(err, "%s: cannot read its image file: %s", path, msg);
  }
  snprintf(pf->data_name, sizeof pf->data_name, "%s (image file %s)", path, pf->img_path);
  pf->ds.name = pf->data_name; /* messages about the voxels name the header too */
  return image_stream_seek(&pf->ds, (int64_t)off);
}

static i2m_err_t nifti_read(image_stream_t *s, const char *path, nifti_pair_t *pf,
                            i2m_image_t **out)
{
  unsigned char h[NIFTI_HDR];
  nifti_t x = {NULL, 0};
  int pair = 0;
  int64_t n[3];
  double axis[3][3], origin[3];
  image_voxels_t vf = {I2M_SCALAR_UINT8, 0, 0, 1.0, 0.0};
  I2M_CALL(nifti_header(s, path, h, &x, &pair));
  I2M_CALL(nifti_dims(&x, path, n));
  I2M_CALL(nifti_type(&x, path, &vf.type));
  vf.big_endian = x.big;
  vf.slope = nifti_f32(&x, OFF_SCL_SLOPE);
  vf.inter = nifti_f32(&x, OFF_SCL_INTER);
  vf.scale = isfinite(vf.slope) && isfinite(vf.inter) && vf.slope != 0 &&
             (vf.slope != 1 || vf.inter != 0);
  I2M_CALL(nifti_geometry(&x, path, axis, origin));
  I2M_CALL(nifti_position(s, &x, path, pair, pf));
  image_stream_t *data = pair ? &pf->ds : s;
  I2M_CALL(image_check_data_size(data, n, vf.type));
  I2M_CALL(image_alloc(path, n, out));
  I2M_CALL(image_set_geometry(*out, axis, origin));
  return image_read_body(s, data, &vf, *out);
}

i2m_err_t image_read_nifti(image_stream_t *s, const char *path, i2m_image_t **out)
{
  nifti_pair_t *pf = NULL;
  *out = NULL;
  I2M_CALL(i2m_calloc(1, sizeof *pf, &pf));
  i2m_err_t err = nifti_read(s, path, pf, out);
  image_stream_close(&pf->ds);
  i2m_free(&pf);
  if (err != I2M_OK) i2m_image_destroy(out);
  return err;
}
