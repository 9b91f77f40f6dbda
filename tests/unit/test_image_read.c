/* Unit tests of the image readers (layer 2).  The seven real images of ../shared/data are read
 * and compared with their labels.json voxel counts and with the geometry their headers state
 * (NIfTI values derived by hand from sform/qform, cross-checked with nibabel).  Synthetic
 * images written by the test-fixture writers (tools/mkimage_write.h) in every format x type x
 * byte order x compression are read back and compared voxel by voxel; then format details
 * (type spellings, spaces, skips, qform, scaling, TransformMatrix order) and error paths. */
#include "../../tools/mkimage_write.h"
#include "test_util.h"

#include <stdint.h>
#include <unistd.h>

/* ---- scratch directory ---- */

static char tmp_dir[256];
static char tmp_buf[512];

static const char *tmp_path(const char *name)
{
  if (!tmp_dir[0]) {
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/i2m_test_image_XXXXXX");
    if (!mkdtemp(tmp_dir)) {
      perror("mkdtemp");
      abort();
    }
  }
  snprintf(tmp_buf, sizeof tmp_buf, "%s/%s", tmp_dir, name);
  return tmp_buf;
}

/* Removes a file and the data files a detached header may have next to it. */
static void tmp_remove(const char *path)
{
  static const char *sib[] = {"", ".raw", ".raw.gz", ".zraw", ".img"};
  char p[600];
  size_t n = strlen(path);
  const char *dot = strrchr(path, '.');
  size_t stem = dot ? (size_t)(dot - path) : n;
  remove(path);
  for (size_t i = 1; i < sizeof sib / sizeof sib[0]; i++) {
    snprintf(p, sizeof p, "%.*s%s", (int)stem, path, sib[i]);
    remove(p);
  }
}

static void write_text(const char *path, const char *text, size_t len)
{
  FILE *f = fopen(path, "wb");
  CU_ASSERT_FATAL(f != NULL);
  CU_ASSERT_FATAL(fwrite(text, 1, len, f) == len);
  fclose(f);
}

/* ---- labels.json: {"labels_voxel_counts": {"0": N, ...}, ...} ---- */

static int read_label_counts(const char *path, int64_t *value, int64_t *count, int cap)
{
  FILE *f = fopen(path, "rb");
  static char text[1 << 16];
  if (!f) return -1;
  size_t len = fread(text, 1, sizeof text - 1, f);
  fclose(f);
  text[len] = '\0';
  char *p = strstr(text, "\"labels_voxel_counts\"");
  if (!p || !(p = strchr(p, '{'))) return -1;
  int n = 0;
  for (p++; n < cap;) {
    char *end;
    while (*p == ' ' || *p == '\n') p++;
    if (*p == '}') return n;
    if (*p++ != '"') return -1;
    value[n] = strtoll(p, &end, 10);
    if (end == p || *end != '"') return -1;
    p = strchr(end, ':');
    if (!p) return -1;
    count[n] = strtoll(p + 1, &end, 10);
    if (end == p + 1) return -1;
    n++;
    for (p = end; *p == ' '; p++) {}
    if (*p == ',') p++;
  }
  return -1;
}

/* ---- the real images ---- */

typedef struct {
  const char *file, *json;
  int64_t n[3];
  i2m_scalar_t type;
  double spacing[3], origin[3], dir[3][3];
} real_t;

static const real_t reals[] = {
    {"knee_atlas.nrrd", "knee_atlas.labels.json", {512, 512, 119}, I2M_SCALAR_INT16,
     {0.27734019657873127, 0.27734019657873127, 1}, {-70.860420225865852, 70.860420225865852, -59},
     {{1, 0, 0}, {0, -1, 0}, {0, 0, 1}}},
    {"abdominal_atlas.nrrd", "abdominal_atlas.labels.json", {256, 256, 113}, I2M_SCALAR_INT16,
     {0.93750000000000022, 0.93750000000000022, 1.5000000000000004},
     {-119.53000000000002, 119.53000000000007, 84.000000000000028},
     {{1, 0, 0}, {0, -1, 0}, {0, 0, -1}}},
    /* sform (code 1): srow_x = (-2 0 0 0), srow_y = (0 0 3 -254), srow_z = (0 2 0 0) in RAS */
    {"brain_kmeans_noisy.nii.gz", "brain_kmeans_noisy.labels.json", {128, 128, 62}, I2M_SCALAR_UINT8,
     {2, 2, 3}, {0, 254, 0}, {{1, 0, 0}, {0, 0, -1}, {0, 1, 0}}},
    /* sform (code 2): identity RAS */
    {"head_colin27.nii.gz", "head_colin27.labels.json", {181, 217, 181}, I2M_SCALAR_UINT8,
     {1, 1, 1}, {0, 0, 0}, {{-1, 0, 0}, {0, -1, 0}, {0, 0, 1}}},
    /* qform only: (b,c,d) = (-0.5, 0.5, -0.5), qfac 1, pixdim (1,1,2), qoffset (-87.712, 25.407, 1.148) */
    {"spine_verse009.nii.gz", "spine_verse009.labels.json", {106, 408, 48}, I2M_SCALAR_UINT8,
     {1, 1, 2}, {87.71207427978516, -25.406946182250977, 1.1479464769363403},
     {{0, 0, -1}, {1, 0, 0}, {0, -1, 0}}},
    {"vertebrae_vbseg.mha", "vertebrae_vbseg.labels.json", {640, 633, 299}, I2M_SCALAR_UINT8,
     {0.34375, 0.34375, 1}, {0, 0, 0}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}},
    {"liver.inr.gz", "liver.labels.json", {438, 353, 165}, I2M_SCALAR_UINT8,
     {0.617188, 0.617188, 1.33333}, {0, 0, 0}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}},
};


static void check_geometry(const i2m_image_t *img, const double sp[3], const double o[3],
                           const double dir[3][3], double tol)
{
  for (int r = 0; r < 3; r++) {
    CU_ASSERT(fabs(img->spacing[r] - sp[r]) <= tol * (1 + fabs(sp[r])));
    CU_ASSERT(fabs(img->origin[r] - o[r]) <= tol * (1 + fabs(o[r])));
    for (int c = 0; c < 3; c++) CU_ASSERT(fabs(img->dir[r][c] - dir[r][c]) <= tol);
  }
}

/* Label indices: 0 = value 0, increasing values, every voxel index valid, and the voxels of
 * each index are as many as label_count says. */
static void check_labels(const i2m_image_t *img)
{
  int64_t nvox = img->n[0] * img->n[1] * img->n[2], total = 0;
  int64_t *hist = calloc((size_t)img->nlabels, sizeof *hist);
  CU_ASSERT_FATAL(hist != NULL);
  CU_ASSERT(img->nlabels >= 1 && img->label_value[0] == 0);
  for (int l = 0; l < img->nlabels; l++) {
    if (l >= 2) CU_ASSERT(img->label_value[l] > img->label_value[l - 1]);
    total += img->label_count[l];
  }
  CU_ASSERT(total == nvox);
  int64_t bad = 0;
  for (int64_t i = 0; i < nvox; i++) {
    if (i2m_image_index(img, i) < img->nlabels) hist[i2m_image_index(img, i)]++;
    else bad++;
  }
  CU_ASSERT(bad == 0);
  for (int l = 0; l < img->nlabels; l++) CU_ASSERT(hist[l] == img->label_count[l]);
  free(hist);
}

static void test_real_images(void)
{
  for (size_t t = 0; t < sizeof reals / sizeof reals[0]; t++) {
    const real_t *e = &reals[t];
    char path[1024];
    int64_t value[256], count[256];
    i2m_image_t *img = NULL;
    snprintf(path, sizeof path, "%s/%s", test_data_dir(), e->file);
    double t0 = i2m_wtime();
    i2m_err_t err = i2m_image_read(path, &img);
    if (err) printf("\n  %s: %s\n", e->file, i2m_error_message());
    CU_ASSERT_FATAL(err == I2M_OK);
    printf("\n  %-28s read in %.2f s, %d labels", e->file, i2m_wtime() - t0, img->nlabels);
    for (int a = 0; a < 3; a++) CU_ASSERT(img->n[a] == e->n[a]);
    CU_ASSERT(img->file_type == e->type);
    check_geometry(img, e->spacing, e->origin, e->dir, 1e-9);
    check_labels(img);
    CU_ASSERT((img->vox_hi == NULL) == (img->nlabels <= 256)); /* one byte per voxel */
    snprintf(path, sizeof path, "%s/%s", test_data_dir(), e->json);
    int n = read_label_counts(path, value, count, 256);
    CU_ASSERT_FATAL(n > 0);
    CU_ASSERT(n == img->nlabels);
    for (int k = 0; k < n && k < img->nlabels; k++) {
      int l = 0;
      while (l < img->nlabels && img->label_value[l] != value[k]) l++;
      CU_ASSERT_FATAL(l < img->nlabels);
      CU_ASSERT(img->label_count[l] == count[k]);
    }
    i2m_image_destroy(&img);
    CU_ASSERT(img == NULL);
  }
}

/* ---- round trips through the fixture writers ---- */

#define RN0 7
#define RN1 6
#define RN2 5
#define RNV (RN0 * RN1 * RN2)

/* Per type: values that stress its range (first is 0). */
static void type_values(i2m_scalar_t t, int64_t v[5])
{
  static const int64_t tab[10][5] = {
      {0, -128, -1, 1, 127},
      {0, 1, 200, 255, 7},
      {0, -32768, -5, 300, 32767},
      {0, 1, 40000, 65535, 9},
      {0, INT32_MIN, -70000, 100000, INT32_MAX},
      {0, 3, 70000, UINT32_MAX, 11},
      {0, INT64_MIN, -5000000000000000, 1000000000000, INT64_MAX},
      {0, 1, (int64_t)1 << 40, INT64_MAX, 13},
      {0, -7, 3, 16777216, -16777216},
      {0, -9007199254740992, 5, 1000000000000000, 17},
  };
  memcpy(v, tab[t], sizeof tab[t]);
}

static void make_values(i2m_scalar_t t, int64_t *vals)
{
  int64_t v[5];
  type_values(t, v);
  for (int i = 0; i < RNV; i++) vals[i] = v[(i * 7 + i / 11) % 5];
  vals[3] = v[4]; /* every value at least once */
}

/* Reads @p path and compares voxels and geometry with what was written. */
static void check_read_back(const char *path, const wimg_image_t *im, i2m_scalar_t t, double tol)
{
  i2m_image_t *img = NULL;
  i2m_err_t err = i2m_image_read(path, &img);
  if (err) printf("\n  %s: %s\n", path, i2m_error_message());
  CU_ASSERT_FATAL(err == I2M_OK);
  for (int a = 0; a < 3; a++) CU_ASSERT(img->n[a] == im->n[a]);
  CU_ASSERT(img->file_type == t);
  check_geometry(img, im->spacing, im->origin, im->dir, tol);
  check_labels(img);
  int64_t nvox = im->n[0] * im->n[1] * im->n[2], bad = 0;
  for (int64_t i = 0; i < nvox; i++) bad += img->label_value[i2m_image_index(img, i)] != im->values[i];
  CU_ASSERT(bad == 0);
  if (bad) printf("\n  %s: %lld voxels differ\n", path, (long long)bad);
  i2m_image_destroy(&img);
}

static void round_trip(const char *name, const wimg_image_t *im, const wimg_opts_t *o, double tol)
{
  char path[600];
  snprintf(path, sizeof path, "%s", tmp_path(name));
  CU_ASSERT_FATAL(wimg_write(path, im, o) == 0);
  check_read_back(path, im, o->type, tol);
  tmp_remove(path);
}

static void test_round_trip_all(void)
{
  static const char *exts[] = {"nrrd", "nhdr", "nii", "nii.gz", "hdr", "mha", "mhd", "inr", "inr.gz"};
  int64_t vals[RNV];
  wimg_image_t im = {{RN0, RN1, RN2}, {0.5, 1.25, 2}, {-10.5, 20.25, 3},
                     {{0, -1, 0}, {1, 0, 0}, {0, 0, -1}}, vals};
  int nfiles = 0;
  for (int e = 0; e < 9; e++)
    for (int t = 0; t < 10; t++)
      for (int big = 0; big < 2; big++)
        for (int gz = 0; gz < 2; gz++) {
          int compressible = e == 0 || e == 1 || e == 5 || e == 6;
          if (gz && !compressible) continue;
          wimg_opts_t o = {(i2m_scalar_t)t, big, gz, 1, 3, 0, 0, 0, t, 0, 0, {0, 0, 0}};
          wimg_image_t w = im;
          if (e >= 7) /* INR: no directions */
            for (int r = 0; r < 3; r++)
              for (int c = 0; c < 3; c++) w.dir[r][c] = r == c;
          make_values((i2m_scalar_t)t, vals);
          char name[64];
          snprintf(name, sizeof name, "rt_%d_%d_%d.%s", t, big, gz, exts[e]);
          round_trip(name, &w, &o, 0);
          nfiles++;
        }
  printf("\n  %d files written and read back exactly", nfiles);
}

/* A larger image whose elements straddle the stream's chunk boundaries (odd header size). */
static void test_chunk_boundaries(void)
{
  int64_t n[3] = {97, 89, 23}, nvox = n[0] * n[1] * n[2];
  int64_t *vals = malloc((size_t)nvox * sizeof *vals);
  CU_ASSERT_FATAL(vals != NULL);
  for (int64_t i = 0; i < nvox; i++) vals[i] = (i * 2654435761u >> 7) % 5 == 0 ? 0 : 1000 + (i / 97) % 17;
  wimg_image_t im = {{n[0], n[1], n[2]}, {1, 1, 1}, {0, 0, 0}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, vals};
  const i2m_scalar_t types[] = {I2M_SCALAR_INT16, I2M_SCALAR_INT64, I2M_SCALAR_FLOAT32};
  for (int t = 0; t < 3; t++)
    for (int gz = 0; gz < 2; gz++) {
      wimg_opts_t o = {types[t], t == 1, gz, gz ? 3 : 1, 3, 0, 0, 0, 1, 0, 0, {0, 0, 0}};
      round_trip("chunks.nrrd", &im, &o, 0);
      round_trip("chunks.nii.gz", &im, &o, 0);
      round_trip("chunks.mha", &im, &o, 0);
    }
  free(vals);
}

/* ---- format details ---- */

static int64_t small_vals[RNV];
static wimg_image_t small_image(void)
{
  wimg_image_t im = {{RN0, RN1, RN2}, {0.5, 1.25, 2}, {-10.5, 20.25, 3},
                     {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, small_vals};
  make_values(I2M_SCALAR_INT16, small_vals);
  return im;
}

static void test_nrrd_variants(void)
{
  wimg_image_t im = small_image();
  const double flip[3][3] = {{-1, 0, 0}, {0, 0, 1}, {0, 1, 0}};
  memcpy(im.dir, flip, sizeof flip);
  for (int space = 0; space < 4; space++) /* LPS, RAS, LAS, 3D-right-handed */
    for (int spelling = 0; spelling < 4; spelling++) {
      wimg_opts_t o = {.type = I2M_SCALAR_INT16, .nrrd_space = space, .nrrd_spelling = spelling};
      round_trip("space.nrrd", &im, &o, 0);
    }
  wimg_opts_t four = {.type = I2M_SCALAR_UINT16, .ndim = 4, .big_endian = 1};
  make_values(I2M_SCALAR_UINT16, small_vals);
  round_trip("fourd.nrrd", &im, &four, 0);       /* 4-D, extra axis of size 1 */
  wimg_opts_t skip = {.type = I2M_SCALAR_UINT16, .nrrd_byte_skip = 1};
  round_trip("skip.nhdr", &im, &skip, 0);        /* byte skip: -1 */
  wimg_opts_t members = {.type = I2M_SCALAR_UINT16, .gzip = 1, .gzip_members = 4};
  round_trip("members.nhdr", &im, &members, 0);  /* several gzip members */
  wimg_image_t legacy = small_image();
  legacy.origin[0] = legacy.origin[1] = legacy.origin[2] = 0;
  wimg_opts_t sp = {.type = I2M_SCALAR_INT16, .nrrd_space = 4};
  round_trip("legacy.nrrd", &legacy, &sp, 0);    /* "spacings", no space */
}

/* Hand-written detached header: "datafile:", line skip, byte skip, CRLF line ends. */
static void test_nrrd_skips(void)
{
  char hdr[600], raw[64];
  const char *text = "NRRD0005\r\n# comment\r\ntype: unsigned char\r\ndimension: 3\r\nsizes: 2 2 2\r\n"
                     "spacings: 2 3 4\r\nencoding: raw\r\nmy key:=my value\r\nline skip: 2\r\n"
                     "byte skip: 3\r\ndatafile: skips.dat\r\n";
  snprintf(hdr, sizeof hdr, "%s", tmp_path("skips.nhdr"));
  write_text(hdr, text, strlen(text));
  memcpy(raw, "line one\nline two\nabc\x00\x05\x05\x00\x09\x00\x00\x05", 29);
  write_text(tmp_path("skips.dat"), raw, 29);
  i2m_image_t *img = NULL;
  i2m_err_t err = i2m_image_read(hdr, &img);
  if (err) printf("\n  %s\n", i2m_error_message());
  CU_ASSERT_FATAL(err == I2M_OK);
  CU_ASSERT(img->nlabels == 3 && img->label_value[1] == 5 && img->label_value[2] == 9);
  CU_ASSERT(img->label_count[0] == 4 && img->label_count[1] == 3 && img->label_count[2] == 1);
  CU_ASSERT(i2m_image_index(img, 1) == 1 && i2m_image_index(img, 4) == 2 && img->spacing[1] == 3);
  i2m_image_destroy(&img);
  remove(tmp_path("skips.dat"));
  remove(hdr);
}

static void test_nifti_variants(void)
{
  wimg_image_t im = small_image();
  /* qform only, exact for 180-degree rotations and flips (quaternion parts 0 or 1, qfac -1) */
  const double m1[3][3] = {{-1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, m2[3][3] = {{1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
  const double m3[3][3] = {{0, -1, 0}, {1, 0, 0}, {0, 0, 1}}; /* 90 degrees: float quaternion */
  const double c = cos(0.3), s = sin(0.3), m4[3][3] = {{c, -s, 0}, {s, c, 0}, {0, 0, -1}};
  const double(*mats[])[3] = {m1, m2, m3, m4};
  for (int k = 0; k < 4; k++) {
    memcpy(im.dir, mats[k], sizeof im.dir);
    wimg_opts_t q = {.type = I2M_SCALAR_INT16, .nifti_form = 2, .big_endian = k & 1};
    round_trip("qform.nii", &im, &q, k < 2 ? 0 : 1e-6);
    wimg_opts_t sf = {.type = I2M_SCALAR_INT16, .nifti_form = 1};
    round_trip("sform.nii.gz", &im, &sf, k < 3 ? 0 : 1e-6);
  }
  /* no sform, no qform: pixdim only, read in RAS as ITK does -> LPS diag(-1,-1,1), origin 0 */
  const double ras[3][3] = {{-1, 0, 0}, {0, -1, 0}, {0, 0, 1}};
  memcpy(im.dir, ras, sizeof ras);
  im.origin[0] = im.origin[1] = im.origin[2] = 0;
  wimg_opts_t none = {.type = I2M_SCALAR_INT16, .nifti_form = 0};
  round_trip("none.nii", &im, &none, 0);
  /* scl_slope / scl_inter: stored (v - inter) / slope */
  for (int i = 0; i < RNV; i++) small_vals[i] = 2 * (i % 5) - 10;
  wimg_opts_t scaled = {.type = I2M_SCALAR_INT16, .nifti_form = 3, .slope = 2, .inter = -10};
  round_trip("scaled.nii", &im, &scaled, 0);
  scaled.type = I2M_SCALAR_FLOAT32;
  round_trip("scaled_f.nii.gz", &im, &scaled, 0);
  wimg_opts_t fourd = {.type = I2M_SCALAR_INT16, .nifti_form = 3, .ndim = 4, .gzip_members = 2};
  round_trip("fourd.nii.gz", &im, &fourd, 0); /* dim[0] = 4, dim[4] = 1 */
}

/* The .img of a pair names the same image as its .hdr. */
static void test_nifti_pair(void)
{
  wimg_image_t im = small_image();
  wimg_opts_t o = {.type = I2M_SCALAR_INT16, .nifti_form = 1, .big_endian = 1};
  char hdr[600];
  snprintf(hdr, sizeof hdr, "%s", tmp_path("pair.hdr"));
  CU_ASSERT_FATAL(wimg_write(hdr, &im, &o) == 0);
  check_read_back(tmp_path("pair.img"), &im, I2M_SCALAR_INT16, 0);
  tmp_remove(hdr);
}

/* TransformMatrix lists axis directions one after the other (ITK's MetaImageIO). */
static void test_metaimage_matrix(void)
{
  const char *text = "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = True\n"
                     "TransformMatrix = 0 1 0 -1 0 0 0 0 1\nPosition = 1 2 3\n"
                     "ElementSize = 0.5 0.5 2\nDimSize = 2 1 1\nElementType = MET_LONG\n"
                     "ElementDataFile = LOCAL\n\x00\x00\x01\x00\xff\xff\xff\xfe";
  char path[600];
  snprintf(path, sizeof path, "%s", tmp_path("matrix.mha"));
  write_text(path, text, strlen(text) + 8);
  i2m_image_t *img = NULL;
  i2m_err_t err = i2m_image_read(path, &img);
  if (err) printf("\n  %s\n", i2m_error_message());
  CU_ASSERT_FATAL(err == I2M_OK);
  const double dir[3][3] = {{0, -1, 0}, {1, 0, 0}, {0, 0, 1}}, sp[3] = {0.5, 0.5, 2}, o[3] = {1, 2, 3};
  check_geometry(img, sp, o, dir, 0);
  CU_ASSERT(img->file_type == I2M_SCALAR_INT32 && img->nlabels == 3);
  CU_ASSERT(img->label_value[1] == -2 && img->label_value[2] == 256 && img->label_count[0] == 0);
  CU_ASSERT(i2m_image_index(img, 0) == 2 && i2m_image_index(img, 1) == 1);
  i2m_image_destroy(&img);
  remove(path);
}

/* Slightly non-orthogonal axes are orthonormalised; sheared ones are refused. */
static void test_orthonormalise(void)
{
  const char *fmt = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nspace: LPS\n"
                    "space directions: (1,0,0) (%g,1,0) (0,0,2)\nencoding: raw\n\n\x03";
  char text[400], path[600];
  i2m_image_t *img = NULL;
  snprintf(path, sizeof path, "%s", tmp_path("skew.nrrd"));
  snprintf(text, sizeof text, fmt, 2e-4);
  write_text(path, text, strlen(text));
  CU_ASSERT_FATAL(i2m_image_read(path, &img) == I2M_OK);
  for (int a = 0; a < 3; a++)
    for (int b = 0; b < 3; b++) {
      double d = img->dir[0][a] * img->dir[0][b] + img->dir[1][a] * img->dir[1][b] + img->dir[2][a] * img->dir[2][b];
      CU_ASSERT(fabs(d - (a == b)) < 1e-14);
    }
  CU_ASSERT(img->nlabels == 2 && img->label_value[1] == 3 && img->label_count[0] == 0);
  i2m_image_destroy(&img);
  snprintf(text, sizeof text, fmt, 0.1);
  write_text(path, text, strlen(text));
  CU_ASSERT(i2m_image_read(path, &img) == I2M_ERR_UNSUPPORTED && img == NULL);
  CU_ASSERT(strstr(i2m_error_message(), "sheared") != NULL);
  remove(path);
}

/* 65534 non-zero values fit (65535 indices with 0); one more does not. */
static void test_label_limit(void)
{
  int64_t n = 65535;
  int64_t *vals = malloc((size_t)n * sizeof *vals);
  CU_ASSERT_FATAL(vals != NULL);
  for (int64_t i = 0; i < n; i++) vals[i] = i == 0 ? 0 : 100000 - 3 * i;
  wimg_image_t im = {{255, 257, 1}, {1, 1, 1}, {0, 0, 0}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, vals};
  wimg_opts_t o = {.type = I2M_SCALAR_INT32, .gzip = 1};
  round_trip("many.mha", &im, &o, 0);
  vals[0] = 100000; /* a 65535th non-zero value */
  char path[600];
  i2m_image_t *img = NULL;
  snprintf(path, sizeof path, "%s", tmp_path("toomany.nrrd"));
  CU_ASSERT_FATAL(wimg_write(path, &im, &o) == 0);
  CU_ASSERT(i2m_image_read(path, &img) == I2M_ERR_UNSUPPORTED && img == NULL);
  CU_ASSERT(strstr(i2m_error_message(), "distinct label values") != NULL);
  tmp_remove(path);
  free(vals);
}

/* 256 non-zero values and no 0: first-seen indices fit in a byte, the final ones (0 is
 * index 0) do not, so the high plane appears only when the indices are renumbered. */
static void test_label_high_plane(void)
{
  int64_t vals[256];
  for (int i = 0; i < 256; i++) vals[i] = 1000 - i;
  wimg_image_t im = {{16, 16, 1}, {1, 1, 1}, {0, 0, 0}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, vals};
  wimg_opts_t o = {.type = I2M_SCALAR_UINT16};
  round_trip("high.nrrd", &im, &o, 0);
}

/* ---- error paths: one message naming the file and the problem, no image ---- */

static void expect_error(const char *path, i2m_err_t code, const char *word)
{
  i2m_image_t *img = (i2m_image_t *)&img; /* must be reset to NULL */
  i2m_err_t err = i2m_image_read(path, &img);
  const char *msg = i2m_error_message(), *base = strrchr(path, '/');
  CU_ASSERT(err == code);
  CU_ASSERT(img == NULL);
  CU_ASSERT(strstr(msg, base ? base + 1 : path) != NULL);
  CU_ASSERT(strstr(msg, word) != NULL);
  CU_ASSERT(strchr(msg, '\n') == NULL);
  if (err != code || !strstr(msg, word)) printf("\n  %s: got %d \"%s\", expected \"%s\"\n", path, err, msg, word);
}

/* Writes a fixture, then cuts @p cut bytes off its end and/or flips byte @p flip (< 0: none). */
static const char *damaged(const char *name, const wimg_image_t *im, const wimg_opts_t *o,
                           long cut, long flip_from_end)
{
  static char path[600];
  snprintf(path, sizeof path, "%s", tmp_path(name));
  CU_ASSERT_FATAL(wimg_write(path, im, o) == 0);
  FILE *f = fopen(path, "rb");
  CU_ASSERT_FATAL(f != NULL);
  static unsigned char buf[1 << 20];
  size_t n = fread(buf, 1, sizeof buf, f);
  fclose(f);
  CU_ASSERT_FATAL(n < sizeof buf && (size_t)cut < n && (size_t)flip_from_end < n);
  if (flip_from_end > 0) buf[n - (size_t)flip_from_end] ^= 0xFF;
  write_text(path, (const char *)buf, n - (size_t)cut);
  return path;
}

static void test_errors_data(void)
{
  int64_t n[3] = {40, 40, 40}, nvox = 64000;
  int64_t *vals = malloc((size_t)nvox * sizeof *vals);
  CU_ASSERT_FATAL(vals != NULL);
  for (int64_t i = 0; i < nvox; i++) { /* noise: about 20 KB of deflate output */
    uint64_t h = (uint64_t)i * 0x9E3779B97F4A7C15ull;
    h = (h ^ h >> 31) * 0xBF58476D1CE4E5B9ull;
    vals[i] = (int64_t)((h >> 40) % 7);
  }
  wimg_image_t im = {{n[0], n[1], n[2]}, {1, 1, 1}, {0, 0, 0}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, vals};
  wimg_opts_t gz = {.type = I2M_SCALAR_INT16, .gzip = 1, .nifti_form = 1};
  wimg_opts_t raw = {.type = I2M_SCALAR_INT16, .nifti_form = 1};
  expect_error(damaged("cut.nrrd", &im, &gz, 5000, 0), I2M_ERR_INPUT, "gzip stream ends after");
  expect_error(damaged("cut.nii.gz", &im, &gz, 3, 0), I2M_ERR_INPUT, "truncated gzip");
  expect_error(damaged("cut.mha", &im, &gz, 100, 0), I2M_ERR_INPUT, "truncated gzip");
  expect_error(damaged("cut.inr", &im, &raw, 1, 0), I2M_ERR_INPUT, "holds only 127999 bytes");
  expect_error(damaged("cut.nii", &im, &raw, 10, 0), I2M_ERR_INPUT, "truncated");
  expect_error(damaged("bad.nrrd", &im, &gz, 0, 3000), I2M_ERR_INPUT, "corrupt gzip");
  expect_error(damaged("crc.inr.gz", &im, &gz, 0, 7), I2M_ERR_INPUT, "corrupt gzip");
  wimg_opts_t lie = {.type = I2M_SCALAR_UINT8, .nifti_form = 1, .lie = {40, 40, 80}};
  expect_error(damaged("lie.nii.gz", &im, &lie, 0, 0), I2M_ERR_INPUT, "ends after 64000 bytes");
  expect_error(damaged("lie.mhd", &im, &lie, 0, 0), I2M_ERR_INPUT, "40x40x80 uint8 (128000 bytes)");
  wimg_opts_t absurd = {.type = I2M_SCALAR_UINT8, .nifti_form = 1, .lie = {32767, 32767, 32767}};
  expect_error(damaged("absurd.nii.gz", &im, &absurd, 0, 0), I2M_ERR_INPUT, "cannot hold");
  wimg_opts_t flat = {.type = I2M_SCALAR_UINT8, .nifti_form = 1, .ndim = 2};
  expect_error(damaged("flat.nii", &im, &flat, 0, 0), I2M_ERR_UNSUPPORTED, "not a 3-D image (dim[0] = 2)");
  expect_error(damaged("flat.nrrd", &im, &flat, 0, 0), I2M_ERR_UNSUPPORTED, "not a 3-D image");
  expect_error(damaged("flat.mha", &im, &flat, 0, 0), I2M_ERR_UNSUPPORTED, "not a 3-D image");
  wimg_opts_t five = {.type = I2M_SCALAR_UINT8, .nifti_form = 1, .ndim = 5};
  expect_error(damaged("five.nii", &im, &five, 0, 0), I2M_ERR_UNSUPPORTED, "not a 3-D image");
  expect_error(damaged("vdim.inr", &im, &five, 0, 0), I2M_ERR_UNSUPPORTED, "VDIM");
  static const char *made[] = {"cut.nrrd", "cut.nii.gz", "cut.mha", "cut.inr", "cut.nii",
                               "bad.nrrd", "crc.inr.gz", "lie.nii.gz", "lie.mhd", "absurd.nii.gz",
                               "flat.nii", "flat.nrrd", "flat.mha", "five.nii", "vdim.inr"};
  for (size_t i = 0; i < sizeof made / sizeof made[0]; i++) tmp_remove(tmp_path(made[i]));
  free(vals);
}

static void test_errors_headers(void)
{
  static const struct {
    const char *name, *text, *word;
    i2m_err_t code;
    size_t len; /* 0: strlen(text) */
  } cases[] = {
      {"type.nrrd", "NRRD0004\ntype: quaternion\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n\nx",
       "unknown type \"quaternion\"", I2M_ERR_INPUT, 0},
      {"huge.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 100000 100000 100000\nencoding: raw\n\nxyz",
       "holds only 3 bytes", I2M_ERR_INPUT, 0},
      {"zero.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 0 4\nencoding: raw\n\nx",
       "must be positive", I2M_ERR_INPUT, 0},
      {"enc.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: bzip2\n\nx",
       "encoding \"bzip2\"", I2M_ERR_UNSUPPORTED, 0},
      {"endian.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n\nxx",
       "endian", I2M_ERR_INPUT, 0},
      {"nodata.nhdr", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n",
       "no data", I2M_ERR_INPUT, 0},
      {"nofile.nhdr", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\ndata file: gone.raw\n",
       "No such file", I2M_ERR_IO, 0},
      {"float.nrrd", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1 1\nendian: little\nencoding: raw\n\n"
       "\x00\x00\x80\x3f\x00\x00\x20\x40", "voxel (1,0,0) holds the non-integer value 2.5", I2M_ERR_INPUT, 85},
      {"nan.nrrd", "NRRD0004\ntype: double\ndimension: 3\nsizes: 1 1 1\nendian: big\nencoding: raw\n\n"
       "\x7f\xf8\x00\x00\x00\x00\x00\x00", "holds NaN", I2M_ERR_INPUT, 83},
      {"u64.nrrd", "NRRD0004\ntype: uint64\ndimension: 3\nsizes: 1 1 1\nendian: big\nencoding: raw\n\n"
       "\xff\x00\x00\x00\x00\x00\x00\x00", "beyond the int64 range", I2M_ERR_INPUT, 83},
      {"empty.nii", "", "empty file", I2M_ERR_INPUT, 0},
      {"garbage.nii", "\x01\x02\x03 this is not an image at all, only a few bytes of text",
       "not a NIfTI-1 file", I2M_ERR_INPUT, 0},
      {"garbage.nrrd", "NRRX", "not a NRRD file", I2M_ERR_INPUT, 0},
      {"garbage.inr", "#INRIMAGE-4#{\nXDIM=2\n", "ends inside the INR header", I2M_ERR_INPUT, 0},
      {"garbage.mha", "\x89PNG\r\n", "not a MetaImage file", I2M_ERR_INPUT, 0},
      {"garbage.xyz", "hello", "unknown image format", I2M_ERR_UNSUPPORTED, 0},
      {"gz.nii.gz", "\x1f\x8b\x08\x00garbage", "truncated gzip", I2M_ERR_INPUT, 0},
      {"gzbad.nii.gz", "\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03\xff\xff\xff\xff", "corrupt gzip", I2M_ERR_INPUT, 14},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    char path[600];
    size_t len = cases[i].len ? cases[i].len : strlen(cases[i].text);
    snprintf(path, sizeof path, "%s", tmp_path(cases[i].name));
    write_text(path, cases[i].text, len);
    expect_error(path, cases[i].code, cases[i].word);
    remove(path);
  }
  expect_error(tmp_path("missing.nrrd"), I2M_ERR_IO, "No such file or directory");
  expect_error(tmp_dir, I2M_ERR_IO, "is a directory");
}

static void test_cleanup(void)
{
  CU_ASSERT(rmdir(tmp_dir) == 0); /* every test removed its files */
}

static const test_case_t cases[] = {
    {"real images: label counts and geometry", test_real_images},
    {"round trip: format x type x endian x compression", test_round_trip_all},
    {"round trip: elements across chunk boundaries", test_chunk_boundaries},
    {"NRRD: spaces, type spellings, 4-D, byte skip -1, gzip members", test_nrrd_variants},
    {"NRRD: datafile, line skip, byte skip, CRLF", test_nrrd_skips},
    {"NIfTI: qform, sform, no form, scaling, 4-D", test_nifti_variants},
    {"NIfTI: .hdr/.img pair", test_nifti_pair},
    {"MetaImage: TransformMatrix order, aliases", test_metaimage_matrix},
    {"geometry: orthonormalise, refuse shear", test_orthonormalise},
    {"labels: 65535 indices at most", test_label_limit},
    {"labels: index 256 after renumbering", test_label_high_plane},
    {"errors: truncated, corrupt, lying, non-3-D data", test_errors_data},
    {"errors: bad headers and files", test_errors_headers},
    {"scratch directory left empty", test_cleanup},
};

TEST_MAIN("image_read", cases)
