/* i2m-mkimage: writes small synthetic label images for tests (not a converter for real data):
 * a few shapes in any of the formats the readers take (tools/mkimage_write.h), with options to
 * produce deliberately broken files (lying sizes, wrong dimension, truncated or corrupt
 * bytes) for the error-path tests. */
#include "mkimage_write.h"

#include <errno.h>

static void usage(FILE *f)
{
  fprintf(f,
      "usage: i2m-mkimage [options] -o OUT\n"
      "Writes a synthetic label image; the format follows OUT's extension: .nrrd .nhdr .nii\n"
      ".nii.gz .hdr (+.img) .mha .mhd (+.raw/.zraw) .inr .inr.gz.  A test fixture generator.\n"
      "  --shape S          ball (default), shells, cube, two-balls, speck, noise\n"
      "  --from IMAGE       instead of a shape: the labels of IMAGE (any format i2m reads), with\n"
      "                     its geometry (--dims, --spacing, --origin, --dir are ignored)\n"
      "  --upsample K       with --from: K x K x K voxels for each of IMAGE's (1-4; the corner of\n"
      "                     the image stays where it was)\n"
      "  --dims NX,NY,NZ    voxels (default 24,20,16)\n"
      "  --spacing X,Y,Z    mm (default 1,1,1)\n"
      "  --origin X,Y,Z     LPS world position of voxel (0,0,0) (default 0,0,0)\n"
      "  --dir D00,D01,...,D22  direction matrix, rows (default identity)\n"
      "  --labels V1,V2,... label values of the shape (default 1,2,3)\n"
      "  --type T           int8 uint8 int16 uint16 int32 uint32 int64 uint64 float32 float64\n"
      "  --big-endian       multi-byte voxels big endian\n"
      "  --gzip             NRRD encoding gzip / MetaImage CompressedData\n"
      "  --gzip-members N   split whole-file gzip (.nii.gz .inr.gz) or NRRD gzip data in N members\n"
      "  --nifti-form F     sform, qform, both (default), none\n"
      "  --scale SLOPE,INTER  NIfTI scl_slope and scl_inter\n"
      "  --nrrd-space S     lps (default), ras, las, 3d, spacings (legacy, no space)\n"
      "  --nrrd-spelling K  0..3: which NRRD name of the type\n"
      "  --nrrd-byte-skip   detached raw NRRD: junk before the data and \"byte skip: -1\"\n"
      "Broken files:\n"
      "  --ndim N           header claims N dimensions (2 or 5; 4 = valid extra axis of size 1)\n"
      "  --lie-dims X,Y,Z   header claims these sizes; the data are of --dims\n"
      "  --truncate-bytes N drop the last N bytes of OUT\n"
      "  --corrupt-at K     flip the bits of byte K of OUT (negative: from the end)\n");
}

static int parse_list(const char *s, double *v, int n)
{
  for (int i = 0; i < n; i++) {
    char *end;
    v[i] = strtod(s, &end);
    if (end == s || (i < n - 1 && *end != ',') || (i == n - 1 && *end)) return 0;
    s = end + 1;
  }
  return 1;
}

typedef struct {
  wimg_image_t im;
  wimg_opts_t o;
  const char *shape, *out, *from;
  int upsample;
  int64_t labels[64];
  int nlabels;
  long long truncate, corrupt;
  int do_corrupt;
} mk_t;

static void make_shape(const mk_t *m, int64_t *v)
{
  const int64_t *n = m->im.n;
  double c[3], rmin = 1e300;
  for (int a = 0; a < 3; a++) {
    c[a] = 0.5 * (double)(n[a] - 1);
    if (0.5 * (double)n[a] < rmin) rmin = 0.5 * (double)n[a];
  }
  for (int64_t k = 0, idx = 0; k < n[2]; k++)
    for (int64_t j = 0; j < n[1]; j++)
      for (int64_t i = 0; i < n[0]; i++, idx++) {
        double x = (double)i - c[0], y = (double)j - c[1], z = (double)k - c[2];
        double r = sqrt(x * x + y * y + z * z);
        const char *s = m->shape;
        int64_t val = 0;
        if (strcmp(s, "ball") == 0) val = r < 0.7 * rmin ? m->labels[0] : 0;
        else if (strcmp(s, "shells") == 0) {
          int shell = (int)(r / (0.9 * rmin) * m->nlabels);
          val = shell < m->nlabels ? m->labels[m->nlabels - 1 - shell] : 0;
        } else if (strcmp(s, "cube") == 0)
          val = fabs(x) <= 0.25 * (double)n[0] && fabs(y) <= 0.25 * (double)n[1] && fabs(z) <= 0.25 * (double)n[2] ? m->labels[0] : 0;
        else if (strcmp(s, "two-balls") == 0) {
          double dx = 0.22 * (double)n[0], rr = 0.22 * (double)n[0];
          double r1 = sqrt((x + dx) * (x + dx) + y * y + z * z), r2 = sqrt((x - dx) * (x - dx) + y * y + z * z);
          val = r1 < rr ? m->labels[0] : r2 < rr ? m->labels[m->nlabels > 1 ? 1 : 0] : 0;
        } else if (strcmp(s, "speck") == 0)
          val = i == n[0] / 2 && j == n[1] / 2 && k == n[2] / 2 ? m->labels[0] : 0;
        else { /* noise: a fixed pseudo-random choice among 0 and the labels */
          uint64_t h = (uint64_t)idx * 0x9E3779B97F4A7C15ull;
          h ^= h >> 29;
          int pick = (int)((h * 0xBF58476D1CE4E5B9ull) >> 40) % (m->nlabels + 1);
          val = pick == 0 ? 0 : m->labels[pick - 1];
        }
        v[idx] = val;
      }
}

static int set_choice(const char *arg, const char *const *names, int n, int *out)
{
  for (int i = 0; i < n; i++)
    if (strcmp(arg, names[i]) == 0) {
      *out = i;
      return 1;
    }
  return 0;
}

/* One option with its argument; returns 0 on a bad option. */
static int option(mk_t *m, const char *opt, const char *arg)
{
  static const char *const types[] = {"int8", "uint8", "int16", "uint16", "int32",
                                      "uint32", "int64", "uint64", "float32", "float64"};
  static const char *const forms[] = {"none", "sform", "qform", "both"};
  static const char *const spaces[] = {"lps", "ras", "las", "3d", "spacings"};
  double v[9];
  int t;
  if (strcmp(opt, "-o") == 0) m->out = arg;
  else if (strcmp(opt, "--shape") == 0) m->shape = arg;
  else if (strcmp(opt, "--from") == 0) m->from = arg;
  else if (strcmp(opt, "--upsample") == 0 && atoi(arg) >= 1 && atoi(arg) <= 4) m->upsample = atoi(arg);
  else if (strcmp(opt, "--dims") == 0 && parse_list(arg, v, 3))
    for (int a = 0; a < 3; a++) m->im.n[a] = (int64_t)v[a];
  else if (strcmp(opt, "--lie-dims") == 0 && parse_list(arg, v, 3))
    for (int a = 0; a < 3; a++) m->o.lie[a] = (int64_t)v[a];
  else if (strcmp(opt, "--spacing") == 0 && parse_list(arg, m->im.spacing, 3)) {}
  else if (strcmp(opt, "--origin") == 0 && parse_list(arg, m->im.origin, 3)) {}
  else if (strcmp(opt, "--dir") == 0 && parse_list(arg, v, 9))
    for (int r = 0; r < 9; r++) m->im.dir[r / 3][r % 3] = v[r];
  else if (strcmp(opt, "--scale") == 0 && parse_list(arg, v, 2)) m->o.slope = v[0], m->o.inter = v[1];
  else if (strcmp(opt, "--type") == 0 && set_choice(arg, types, 10, &t)) m->o.type = (i2m_scalar_t)t;
  else if (strcmp(opt, "--nifti-form") == 0 && set_choice(arg, forms, 4, &m->o.nifti_form)) {}
  else if (strcmp(opt, "--nrrd-space") == 0 && set_choice(arg, spaces, 5, &m->o.nrrd_space)) {}
  else if (strcmp(opt, "--nrrd-spelling") == 0) m->o.nrrd_spelling = atoi(arg);
  else if (strcmp(opt, "--gzip-members") == 0) m->o.gzip_members = atoi(arg);
  else if (strcmp(opt, "--ndim") == 0) m->o.ndim = atoi(arg);
  else if (strcmp(opt, "--truncate-bytes") == 0) m->truncate = atoll(arg);
  else if (strcmp(opt, "--corrupt-at") == 0) m->corrupt = atoll(arg), m->do_corrupt = 1;
  else if (strcmp(opt, "--labels") == 0) {
    char *end;
    for (const char *p = arg; *p && m->nlabels < 64; p = *end ? end + 1 : end) {
      m->labels[m->nlabels++] = strtoll(p, &end, 10);
      if (end == p) return 0;
    }
  } else return 0;
  return 1;
}

/* --truncate-bytes and --corrupt-at, applied to the written file. */
static int damage(const mk_t *m)
{
  FILE *f = fopen(m->out, "rb");
  if (!f) return -1;
  fseek(f, 0, SEEK_END);
  long size = ftell(f);
  unsigned char *b = malloc((size_t)size + 1);
  int ok = b && fseek(f, 0, SEEK_SET) == 0 && fread(b, 1, (size_t)size, f) == (size_t)size;
  fclose(f);
  long len = size - (long)m->truncate, at = m->corrupt < 0 ? size + (long)m->corrupt : (long)m->corrupt;
  if (len < 0) len = 0;
  if (ok && m->do_corrupt && at >= 0 && at < len) b[at] ^= 0xFF;
  f = ok ? fopen(m->out, "wb") : NULL;
  ok = f && fwrite(b, 1, (size_t)len, f) == (size_t)len;
  if (f && fclose(f) != 0) ok = 0;
  free(b);
  return ok ? 0 : -1;
}

/* --from IMAGE [--upsample K]: IMAGE's labels, each voxel split into K^3 (nearest neighbour),
 * its geometry with the spacing divided by K and the origin moved so the corner stays. */
static int64_t *from_image(mk_t *m)
{
  i2m_image_t *img = NULL;
  if (i2m_image_read(m->from, &img) != I2M_OK) {
    fprintf(stderr, "i2m-mkimage: %s\n", i2m_error_message());
    return NULL;
  }
  const int K = m->upsample ? m->upsample : 1;
  for (int a = 0; a < 3; a++) {
    m->im.n[a] = K * img->n[a];
    m->im.spacing[a] = img->spacing[a] / K;
  }
  for (int r = 0; r < 3; r++) {
    m->im.origin[r] = img->origin[r];
    for (int c = 0; c < 3; c++) {
      m->im.dir[r][c] = img->dir[r][c];
      m->im.origin[r] += img->dir[r][c] * img->spacing[c] * (-0.5 + 0.5 / K); /* (the corner stays) */
    }
  }
  const int64_t *n = m->im.n, total = n[0] * n[1] * n[2];
  int64_t *v = total <= (int64_t)1 << 31 ? malloc((size_t)total * sizeof *v) : NULL;
  if (v) {
#pragma omp parallel for schedule(static)
    for (int64_t k = 0; k < n[2]; k++)
      for (int64_t j = 0; j < n[1]; j++)
        for (int64_t i = 0; i < n[0]; i++)
          v[(k * n[1] + j) * n[0] + i] = img->label_value[i2m_image_label_voxel(img, i / K, j / K, k / K)];
  } else {
    fprintf(stderr, "i2m-mkimage: out of memory for %lld voxels\n", (long long)total);
  }
  i2m_image_destroy(&img);
  return v;
}

int main(int argc, char **argv)
{
  mk_t m;
  memset(&m, 0, sizeof m);
  m.shape = "ball";
  m.im.n[0] = 24, m.im.n[1] = 20, m.im.n[2] = 16;
  m.o.type = I2M_SCALAR_UINT8;
  m.o.nifti_form = 3;
  for (int a = 0; a < 3; a++) m.im.spacing[a] = m.im.dir[a][a] = 1;
  for (int i = 1; i < argc; i++) {
    const char *opt = argv[i];
    if (strcmp(opt, "--help") == 0 || strcmp(opt, "-h") == 0) return usage(stdout), 0;
    if (strcmp(opt, "--big-endian") == 0) m.o.big_endian = 1;
    else if (strcmp(opt, "--gzip") == 0) m.o.gzip = 1;
    else if (strcmp(opt, "--nrrd-byte-skip") == 0) m.o.nrrd_byte_skip = 1;
    else if (i + 1 >= argc || !option(&m, opt, argv[i + 1])) {
      fprintf(stderr, "i2m-mkimage: bad option %s%s%s (try --help)\n", opt, i + 1 < argc ? " " : "",
              i + 1 < argc ? argv[i + 1] : "");
      return 2;
    } else i++;
  }
  if (m.nlabels == 0) m.labels[0] = 1, m.labels[1] = 2, m.labels[2] = 3, m.nlabels = 3;
  int64_t *v = NULL;
  if (m.from) {
    if (!m.out) return fprintf(stderr, "i2m-mkimage: need -o OUT (try --help)\n"), 2;
    if (!(v = from_image(&m))) return 1;
  } else {
    if (!m.out || m.im.n[0] < 1 || m.im.n[1] < 1 || m.im.n[2] < 1 || m.im.n[0] * m.im.n[1] * m.im.n[2] > 100000000) {
      fprintf(stderr, "i2m-mkimage: need -o OUT and dims of at most 1e8 voxels (try --help)\n");
      return 2;
    }
    v = malloc((size_t)(m.im.n[0] * m.im.n[1] * m.im.n[2]) * sizeof *v);
    if (!v) return fprintf(stderr, "i2m-mkimage: out of memory\n"), 1;
    make_shape(&m, v);
  }
  m.im.values = v;
  int err = wimg_write(m.out, &m.im, &m.o);
  free(v);
  if (!err && (m.truncate > 0 || m.do_corrupt)) err = damage(&m);
  if (err) fprintf(stderr, "i2m-mkimage: cannot write %s: %s\n", m.out, errno ? strerror(errno) : "unknown extension");
  return err ? 1 : 0;
}
