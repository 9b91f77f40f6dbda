/* Test-fixture writers for label images: NRRD (attached/detached, raw/gzip), NIfTI-1 (.nii,
 * .nii.gz, .hdr/.img pair; sform and/or qform), MetaImage (.mha/.mhd, raw or zlib) and INR
 * (.inr/.inr.gz), any voxel type, either byte order.  Included (header-only, static) by
 * tools/i2m_mkimage.c and tests/unit/test_image_read.c; not part of the library: they write
 * what the readers must accept, plus deliberately wrong headers for error tests.  Geometry is
 * given in i2m's LPS world and converted to each format's convention. */
#ifndef I2M_MKIMAGE_WRITE_H
#define I2M_MKIMAGE_WRITE_H

#include "i2m/image.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/** What to write and how. */
typedef struct {
  int64_t n[3];           /* voxels per axis */
  double spacing[3], origin[3], dir[3][3]; /* LPS geometry, dir[r][c] */
  const int64_t *values;  /* borrowed: [n2][n1][n0] label values */
} wimg_image_t;

typedef struct {
  i2m_scalar_t type;      /* voxel type in the file */
  int big_endian;         /* byte order of multi-byte voxels */
  int gzip;               /* NRRD encoding gzip, MetaImage CompressedData (.nii.gz/.inr.gz: by name) */
  int gzip_members;       /* > 1: split the gzip data into that many concatenated members */
  int nifti_form;         /* NIfTI: 1 sform, 2 qform, 3 both, 0 neither */
  double slope, inter;    /* NIfTI scl_slope, scl_inter (slope 0: none) */
  int nrrd_space;         /* NRRD: 0 LPS, 1 RAS, 2 LAS, 3 3D-right-handed, 4 legacy spacings */
  int nrrd_spelling;      /* NRRD: which spelling of the type name (cycles) */
  int nrrd_byte_skip;     /* NRRD detached raw: 1 = prefix junk and write "byte skip: -1" */
  int ndim;               /* 0 or 3: normal; 4: an extra single-sample axis (accepted);
                             2 or 5: header claims that many dimensions (errors) */
  int64_t lie[3];         /* non-zero: header claims these sizes, data are of n[] */
} wimg_opts_t;

static size_t wimg_size(i2m_scalar_t t)
{
  static const size_t s[] = {1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
  return s[t];
}

/* Label value -> file bytes (value = slope * stored + inter when slope != 0). */
static void wimg_encode(int64_t v, const wimg_opts_t *o, unsigned char *p)
{
  double d = o->slope != 0 ? ((double)v - o->inter) / o->slope : (double)v;
  int64_t iv = o->slope != 0 ? (int64_t)llround(d) : v;
  uint64_t u = (uint64_t)iv;
  size_t size = wimg_size(o->type);
  if (o->type == I2M_SCALAR_FLOAT32) {
    float f = (float)d;
    uint32_t u32;
    memcpy(&u32, &f, 4);
    u = u32;
  } else if (o->type == I2M_SCALAR_FLOAT64) {
    memcpy(&u, &d, 8);
  }
  for (size_t b = 0; b < size; b++) p[o->big_endian ? size - 1 - b : b] = (unsigned char)(u >> (8 * b));
}

/* All voxels encoded: *out malloc'ed, *len bytes. */
static int wimg_voxels(const wimg_image_t *im, const wimg_opts_t *o, unsigned char **out, size_t *len)
{
  size_t nvox = (size_t)(im->n[0] * im->n[1] * im->n[2]), size = wimg_size(o->type);
  *len = nvox * size;
  *out = malloc(*len ? *len : 1);
  if (!*out) return -1;
  for (size_t i = 0; i < nvox; i++) wimg_encode(im->values[i], o, *out + i * size);
  return 0;
}

/* Compresses data (gzip wrapper, or zlib when zlib_wrap) into *out (malloc'ed). */
static int wimg_deflate(const unsigned char *data, size_t len, int zlib_wrap, int members,
                        unsigned char **out, size_t *olen)
{
  if (members < 1) members = 1;
  size_t cap = 0, used = 0, start = 0;
  *out = NULL;
  for (int m = 0; m < members; m++) {
    size_t end = m == members - 1 ? len : len / (size_t)members * (size_t)(m + 1);
    z_stream z;
    memset(&z, 0, sizeof z);
    if (deflateInit2(&z, 6, Z_DEFLATED, zlib_wrap ? 15 : 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) return -1;
    size_t bound = deflateBound(&z, (uLong)(end - start)) + 64;
    unsigned char *grown = realloc(*out, cap + bound);
    if (!grown) { deflateEnd(&z); return -1; }
    *out = grown;
    cap += bound;
    z.next_in = (Bytef *)(uintptr_t)(data + start);
    z.avail_in = (uInt)(end - start);
    z.next_out = *out + used;
    z.avail_out = (uInt)(cap - used);
    int r = deflate(&z, Z_FINISH);
    used = cap - z.avail_out;
    deflateEnd(&z);
    if (r != Z_STREAM_END) return -1;
    start = end;
  }
  *olen = used;
  return 0;
}

static int wimg_put(FILE *f, const void *p, size_t n) { return n == 0 || fwrite(p, 1, n, f) == n ? 0 : -1; }

/* Writes head[hlen] then body[blen] (both optional) to path, gzip-compressing the whole file
 * when gz. */
static int wimg_file(const char *path, const void *head, size_t hlen, const void *body, size_t blen,
                     int gz, int members)
{
  FILE *f = fopen(path, "wb");
  int err = f ? 0 : -1;
  if (!err && gz) {
    unsigned char *all = malloc(hlen + blen + 1), *z = NULL;
    size_t zlen = 0;
    err = all ? 0 : -1;
    if (!err) {
      if (hlen) memcpy(all, head, hlen);
      if (blen) memcpy(all + hlen, body, blen);
      err = wimg_deflate(all, hlen + blen, 0, members, &z, &zlen);
    }
    if (!err) err = wimg_put(f, z, zlen);
    free(all);
    free(z);
  } else if (!err) {
    err = wimg_put(f, head, hlen);
    if (!err) err = wimg_put(f, body, blen);
  }
  if (f && fclose(f) != 0) err = -1;
  return err;
}

static int wimg_ends(const char *s, const char *suffix)
{
  size_t n = strlen(s), m = strlen(suffix);
  return n >= m && strcmp(s + n - m, suffix) == 0;
}

static const char *wimg_base(const char *path)
{
  const char *s = strrchr(path, '/');
  return s ? s + 1 : path;
}

/* Sizes as the header states them. */
static void wimg_dims(const wimg_image_t *im, const wimg_opts_t *o, int64_t d[3])
{
  for (int a = 0; a < 3; a++) d[a] = o->lie[a] ? o->lie[a] : im->n[a];
}

/* ---- NRRD ---- */

static const char *wimg_nrrd_type(i2m_scalar_t t, int spelling)
{
  static const char *names[10][4] = {
      {"int8", "signed char", "int8_t", "int8"},
      {"uchar", "unsigned char", "uint8", "uint8_t"},
      {"short", "signed short int", "int16", "short  int"},
      {"ushort", "unsigned short", "uint16_t", "unsigned short int"},
      {"int", "signed int", "int32", "int32_t"},
      {"uint", "unsigned int", "uint32", "uint32_t"},
      {"longlong", "long long int", "int64", "signed long long"},
      {"ulonglong", "unsigned long long", "uint64", "unsigned long long int"},
      {"float", "float", "float", "float"},
      {"double", "double", "double", "double"}};
  return names[t][spelling & 3];
}

/* The header text into h[cap] (data file name into dpath when detached); returns its length. */
static size_t wimg_nrrd_header(char *h, size_t cap, const char *path, char *dpath,
                               const wimg_image_t *im, const wimg_opts_t *o)
{
  static const char *spaces[] = {"left-posterior-superior", "right-anterior-superior",
                                 "left-anterior-superior", "3D-right-handed"};
  static const double sx[] = {1, -1, 1, 1}, sy[] = {1, -1, -1, 1};
  int sp = o->nrrd_space;
  int64_t d[3];
  size_t n = 0;
  wimg_dims(im, o, d);
  n += (size_t)snprintf(h + n, cap - n, "NRRD0004\n# i2m-mkimage test fixture\ntype: %s\n",
                        wimg_nrrd_type(o->type, o->nrrd_spelling));
  if (o->ndim == 2)
    n += (size_t)snprintf(h + n, cap - n, "dimension: 2\nsizes: %lld %lld\n", (long long)d[0], (long long)d[1]);
  else /* ndim 4: a leading single-sample axis, as a 1-component vector image */
    n += (size_t)snprintf(h + n, cap - n, "dimension: %d\nsizes: %s%lld %lld %lld\n",
                          o->ndim == 4 ? 4 : 3, o->ndim == 4 ? "1 " : "", (long long)d[0],
                          (long long)d[1], (long long)d[2]);
  if (sp == 4) {
    n += (size_t)snprintf(h + n, cap - n, "spacings: %.17g %.17g %.17g\n", im->spacing[0],
                          im->spacing[1], im->spacing[2]);
  } else {
    n += (size_t)snprintf(h + n, cap - n, "space: %s\nspace directions:%s", spaces[sp],
                          o->ndim == 4 ? " none" : "");
    for (int c = 0; c < 3; c++)
      n += (size_t)snprintf(h + n, cap - n, " (%.17g,%.17g,%.17g)",
                            sx[sp] * im->dir[0][c] * im->spacing[c], sy[sp] * im->dir[1][c] * im->spacing[c],
                            im->dir[2][c] * im->spacing[c]);
    n += (size_t)snprintf(h + n, cap - n, "\nspace origin: (%.17g,%.17g,%.17g)\n",
                          sx[sp] * im->origin[0], sy[sp] * im->origin[1], im->origin[2]);
  }
  n += (size_t)snprintf(h + n, cap - n, "kinds:%s domain domain domain\nendian: %s\nencoding: %s\n",
                        o->ndim == 4 ? " scalar" : "", o->big_endian ? "big" : "little",
                        o->gzip ? "gzip" : "raw");
  if (!wimg_ends(path, ".nhdr")) return n + (size_t)snprintf(h + n, cap - n, "\n");
  snprintf(dpath, 4096, "%.*s.%s", (int)(strlen(path) - 5), path, o->gzip ? "raw.gz" : "raw");
  n += (size_t)snprintf(h + n, cap - n, "data file: %s\n", wimg_base(dpath));
  if (o->nrrd_byte_skip && !o->gzip) n += (size_t)snprintf(h + n, cap - n, "byte skip: -1\n");
  return n;
}

static int wimg_nrrd(const char *path, const wimg_image_t *im, const wimg_opts_t *o)
{
  char h[4096], dpath[4096];
  int detached = wimg_ends(path, ".nhdr");
  size_t n = wimg_nrrd_header(h, sizeof h, path, dpath, im, o);
  unsigned char *vox = NULL, *z = NULL;
  size_t vlen, zlen = 0;
  int err = wimg_voxels(im, o, &vox, &vlen);
  if (!err && o->gzip) err = wimg_deflate(vox, vlen, 0, o->gzip_members, &z, &zlen);
  const unsigned char *body = o->gzip ? z : vox;
  size_t blen = o->gzip ? zlen : vlen;
  if (!err && detached) {
    err = wimg_file(path, h, n, NULL, 0, 0, 1);
    const char junk[] = "junk before the data, skipped by byte skip -1\n";
    int skip = o->nrrd_byte_skip && !o->gzip;
    if (!err) err = wimg_file(dpath, skip ? junk : NULL, skip ? sizeof junk - 1 : 0, body, blen, 0, 1);
  } else if (!err) {
    err = wimg_file(path, h, n, body, blen, 0, 1);
  }
  free(vox);
  free(z);
  return err;
}

/* ---- NIfTI-1 ---- */

static void wimg_le(unsigned char *h, size_t off, uint64_t v, size_t size, int big)
{
  for (size_t b = 0; b < size; b++) h[off + (big ? size - 1 - b : b)] = (unsigned char)(v >> (8 * b));
}

static void wimg_f32(unsigned char *h, size_t off, double v, int big)
{
  float f = (float)v;
  uint32_t u;
  memcpy(&u, &f, 4);
  wimg_le(h, off, u, 4, big);
}

/* Unit quaternion (b,c,d; a >= 0) of a proper rotation R. */
static void wimg_quatern(double R[3][3], double q[3])
{
  double a, b, c, d, t = R[0][0] + R[1][1] + R[2][2];
  if (t > 0) {
    double s = 0.5 / sqrt(t + 1);
    a = 0.25 / s, b = (R[2][1] - R[1][2]) * s, c = (R[0][2] - R[2][0]) * s, d = (R[1][0] - R[0][1]) * s;
  } else if (R[0][0] > R[1][1] && R[0][0] > R[2][2]) {
    double s = 2 * sqrt(1 + R[0][0] - R[1][1] - R[2][2]);
    a = (R[2][1] - R[1][2]) / s, b = 0.25 * s, c = (R[0][1] + R[1][0]) / s, d = (R[0][2] + R[2][0]) / s;
  } else if (R[1][1] > R[2][2]) {
    double s = 2 * sqrt(1 + R[1][1] - R[0][0] - R[2][2]);
    a = (R[0][2] - R[2][0]) / s, b = (R[0][1] + R[1][0]) / s, c = 0.25 * s, d = (R[1][2] + R[2][1]) / s;
  } else {
    double s = 2 * sqrt(1 + R[2][2] - R[0][0] - R[1][1]);
    a = (R[1][0] - R[0][1]) / s, b = (R[0][2] + R[2][0]) / s, c = (R[1][2] + R[2][1]) / s, d = 0.25 * s;
  }
  double sg = a < 0 ? -1 : 1;
  q[0] = sg * b, q[1] = sg * c, q[2] = sg * d;
}

static void wimg_nifti_geometry(unsigned char *h, const wimg_image_t *im, const wimg_opts_t *o)
{
  int big = o->big_endian;
  double R[3][3], sg[3] = {-1, -1, 1}; /* LPS -> RAS */
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) R[r][c] = sg[r] * im->dir[r][c];
  double det = R[0][0] * (R[1][1] * R[2][2] - R[1][2] * R[2][1]) -
               R[0][1] * (R[1][0] * R[2][2] - R[1][2] * R[2][0]) +
               R[0][2] * (R[1][0] * R[2][1] - R[1][1] * R[2][0]);
  double qfac = det < 0 ? -1 : 1;
  wimg_f32(h, 76, qfac, big);
  for (int a = 0; a < 3; a++) wimg_f32(h, 80 + 4 * a, im->spacing[a], big);
  if (o->nifti_form & 2) {
    double q[3];
    for (int r = 0; r < 3; r++) R[r][2] *= qfac;
    wimg_quatern(R, q);
    wimg_le(h, 252, 1, 2, big);
    for (int k = 0; k < 3; k++) wimg_f32(h, 256 + 4 * k, q[k], big);
    for (int r = 0; r < 3; r++) wimg_f32(h, 268 + 4 * r, sg[r] * im->origin[r], big);
  }
  if (o->nifti_form & 1) {
    wimg_le(h, 254, 2, 2, big);
    for (int r = 0; r < 3; r++) {
      for (int c = 0; c < 3; c++) wimg_f32(h, 280 + 16 * r + 4 * c, sg[r] * im->dir[r][c] * im->spacing[c], big);
      wimg_f32(h, 280 + 16 * r + 12, sg[r] * im->origin[r], big);
    }
  }
}

static int wimg_nifti(const char *path, const wimg_image_t *im, const wimg_opts_t *o)
{
  static const int codes[] = {256, 2, 4, 512, 8, 768, 1024, 1280, 16, 64};
  unsigned char h[352];
  int big = o->big_endian, pair = wimg_ends(path, ".hdr"), gz = wimg_ends(path, ".gz");
  int64_t d[3];
  memset(h, 0, sizeof h);
  wimg_dims(im, o, d);
  wimg_le(h, 0, 348, 4, big);
  wimg_le(h, 40, (uint64_t)(o->ndim ? o->ndim : 3), 2, big);
  for (int a = 0; a < 3; a++) wimg_le(h, 42 + 2 * a, (uint64_t)d[a], 2, big);
  for (int a = 3; a < 7; a++) wimg_le(h, 42 + 2 * a, o->ndim == 5 && a == 4 ? 2 : 1, 2, big);
  wimg_le(h, 70, (uint64_t)codes[o->type], 2, big);
  wimg_le(h, 72, 8 * wimg_size(o->type), 2, big);
  wimg_f32(h, 108, pair ? 0 : 352, big);
  wimg_f32(h, 112, o->slope, big);
  wimg_f32(h, 116, o->slope != 0 ? o->inter : 0, big);
  h[123] = 10; /* xyzt_units: mm */
  wimg_nifti_geometry(h, im, o);
  memcpy(h + 344, pair ? "ni1" : "n+1", 4);
  unsigned char *vox = NULL;
  size_t vlen;
  int err = wimg_voxels(im, o, &vox, &vlen);
  if (!err && pair) {
    char ipath[4096];
    snprintf(ipath, sizeof ipath, "%.*s.img", (int)(strlen(path) - 4), path);
    err = wimg_file(path, h, 348, NULL, 0, 0, 1);
    if (!err) err = wimg_file(ipath, NULL, 0, vox, vlen, 0, 1);
  } else if (!err) {
    err = wimg_file(path, h, 352, vox, vlen, gz, o->gzip_members);
  }
  free(vox);
  return err;
}

/* ---- MetaImage ---- */

static int wimg_meta(const char *path, const wimg_image_t *im, const wimg_opts_t *o)
{
  static const char *types[] = {"MET_CHAR", "MET_UCHAR", "MET_SHORT", "MET_USHORT", "MET_INT",
                                "MET_UINT", "MET_LONG_LONG", "MET_ULONG_LONG", "MET_FLOAT", "MET_DOUBLE"};
  int detached = wimg_ends(path, ".mhd"), nd = o->ndim ? o->ndim : 3;
  char h[4096], dpath[4096];
  int64_t d[3];
  size_t n = 0, vlen, zlen = 0;
  unsigned char *vox = NULL, *z = NULL;
  wimg_dims(im, o, d);
  int err = wimg_voxels(im, o, &vox, &vlen);
  if (!err && o->gzip) err = wimg_deflate(vox, vlen, 1, 1, &z, &zlen);
  n += (size_t)snprintf(h + n, sizeof h - n, "ObjectType = Image\nNDims = %d\nBinaryData = True\n"
                        "BinaryDataByteOrderMSB = %s\nCompressedData = %s\n", nd,
                        o->big_endian ? "True" : "False", o->gzip ? "True" : "False");
  if (o->gzip) n += (size_t)snprintf(h + n, sizeof h - n, "CompressedDataSize = %zu\n", zlen);
  n += (size_t)snprintf(h + n, sizeof h - n, "TransformMatrix =");
  for (int c = 0; c < 3; c++) /* ITK: the direction of axis 0, then of axis 1, ... */
    for (int r = 0; r < 3; r++) n += (size_t)snprintf(h + n, sizeof h - n, " %.17g", im->dir[r][c]);
  n += (size_t)snprintf(h + n, sizeof h - n, "\nOffset = %.17g %.17g %.17g\nCenterOfRotation = 0 0 0\n"
                        "AnatomicalOrientation = RAI\nElementSpacing = %.17g %.17g %.17g\n",
                        im->origin[0], im->origin[1], im->origin[2], im->spacing[0], im->spacing[1],
                        im->spacing[2]);
  if (nd == 2)
    n += (size_t)snprintf(h + n, sizeof h - n, "DimSize = %lld %lld\n", (long long)d[0], (long long)d[1]);
  else
    n += (size_t)snprintf(h + n, sizeof h - n, "DimSize = %lld %lld %lld%s\n", (long long)d[0],
                          (long long)d[1], (long long)d[2], nd == 4 ? " 1" : "");
  n += (size_t)snprintf(h + n, sizeof h - n, "ElementType = %s\n", types[o->type]);
  if (detached)
    snprintf(dpath, sizeof dpath, "%.*s.%s", (int)(strlen(path) - 4), path, o->gzip ? "zraw" : "raw");
  n += (size_t)snprintf(h + n, sizeof h - n, "ElementDataFile = %s\n", detached ? wimg_base(dpath) : "LOCAL");
  const unsigned char *body = o->gzip ? z : vox;
  size_t blen = o->gzip ? zlen : vlen;
  if (!err) err = wimg_file(path, h, n, detached ? NULL : body, detached ? 0 : blen, 0, 1);
  if (!err && detached) err = wimg_file(dpath, NULL, 0, body, blen, 0, 1);
  free(vox);
  free(z);
  return err;
}

/* ---- INR ---- */

static int wimg_inr(const char *path, const wimg_image_t *im, const wimg_opts_t *o)
{
  static const char *types[] = {"signed fixed", "unsigned fixed", "signed fixed", "unsigned fixed",
                                "signed fixed", "unsigned fixed", "signed fixed", "unsigned fixed",
                                "float", "float"};
  char h[1024];
  int64_t d[3];
  wimg_dims(im, o, d);
  size_t n = (size_t)snprintf(h, sizeof h,
                              "#INRIMAGE-4#{\nXDIM=%lld\nYDIM=%lld\nZDIM=%lld\nVDIM=%d\nTYPE=%s\n"
                              "PIXSIZE=%zu bits\nSCALE=2**0\nCPU=%s\nVX=%.17g\nVY=%.17g\nVZ=%.17g\n",
                              (long long)d[0], (long long)d[1], (long long)d[2], o->ndim == 5 ? 2 : 1,
                              types[o->type], 8 * wimg_size(o->type), o->big_endian ? "sun" : "decm",
                              im->spacing[0], im->spacing[1], im->spacing[2]);
  if (im->origin[0] != 0 || im->origin[1] != 0 || im->origin[2] != 0)
    n += (size_t)snprintf(h + n, sizeof h - n, "XO=%.17g\nYO=%.17g\nZO=%.17g\n", im->origin[0],
                          im->origin[1], im->origin[2]);
  size_t total = (n + 4 + 255) / 256 * 256;
  memset(h + n, '\n', total - 4 - n);
  memcpy(h + total - 4, "##}\n", 4);
  unsigned char *vox = NULL;
  size_t vlen;
  int err = wimg_voxels(im, o, &vox, &vlen);
  if (!err) err = wimg_file(path, h, total, vox, vlen, wimg_ends(path, ".gz"), o->gzip_members);
  free(vox);
  return err;
}

/** Writes the image; the format comes from the extension of @p path.  Returns 0 on success,
 *  -1 on an I/O error or unknown extension. */
static int wimg_write(const char *path, const wimg_image_t *im, const wimg_opts_t *o)
{
  if (wimg_ends(path, ".nrrd") || wimg_ends(path, ".nhdr")) return wimg_nrrd(path, im, o);
  if (wimg_ends(path, ".nii") || wimg_ends(path, ".nii.gz") || wimg_ends(path, ".hdr"))
    return wimg_nifti(path, im, o);
  if (wimg_ends(path, ".mha") || wimg_ends(path, ".mhd")) return wimg_meta(path, im, o);
  if (wimg_ends(path, ".inr") || wimg_ends(path, ".inr.gz")) return wimg_inr(path, im, o);
  return -1;
}

#endif
