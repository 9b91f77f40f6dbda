/* Unit tests of tissue names (layer 2): the 3D Slicer colour table beside an image (the knee
 * atlas's knee_atlas.ctbl; a malformed table, a missing one, names with spaces), and 3D Slicer
 * segmentations (.seg.nrrd) of one and of two layers: segment names, label values kept or
 * renumbered, overlaps between layers. */
#include "../../src/image/image_impl.h"
#include "../../tools/mkimage_write.h"
#include "test_util.h"

#include <unistd.h>

static char tmp_dir[256];
static char tmp_buf[512];

static const char *tmp_path(const char *name)
{
  if (!tmp_dir[0]) {
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/i2m_test_names_XXXXXX");
    if (!mkdtemp(tmp_dir)) {
      perror("mkdtemp");
      abort();
    }
  }
  snprintf(tmp_buf, sizeof tmp_buf, "%s/%s", tmp_dir, name);
  return tmp_buf;
}

static void write_text(const char *name, const char *text)
{
  FILE *f = fopen(tmp_path(name), "w");
  CU_ASSERT_FATAL(f != NULL);
  fputs(text, f);
  fclose(f);
}

/* A 4x3x2 uint8 NRRD "<stem>.nrrd" holding the values 0, 5, 7 and 300 (uint16). */
static void write_small_image(const char *stem)
{
  int64_t vals[24];
  for (int i = 0; i < 24; i++) vals[i] = i % 4 == 0 ? 0 : i % 4 == 1 ? 5 : i % 4 == 2 ? 7 : 300;
  wimg_image_t im = {{4, 3, 2}, {1, 1, 1}, {0, 0, 0}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, vals};
  wimg_opts_t o = {.type = I2M_SCALAR_UINT16};
  char name[256];
  snprintf(name, sizeof name, "%s.nrrd", stem);
  CU_ASSERT_FATAL(wimg_write(tmp_path(name), &im, &o) == 0);
}

static i2m_image_t *read_tmp(const char *name)
{
  i2m_image_t *img = NULL;
  i2m_err_t err = i2m_image_read(tmp_path(name), &img);
  if (err) printf("\n  %s: %s\n", name, i2m_error_message());
  CU_ASSERT_FATAL(err == I2M_OK);
  return img;
}

/* Image a unpacked from b's description and voxels: the same in every field. */
static void assert_same_image(const i2m_image_t *a, const i2m_image_t *b)
{
  const size_t nvox = (size_t)(a->n[0] * a->n[1] * a->n[2]);
  CU_ASSERT(memcmp(a->n, b->n, sizeof a->n) == 0 && memcmp(a->spacing, b->spacing, sizeof a->spacing) == 0);
  CU_ASSERT(memcmp(a->origin, b->origin, sizeof a->origin) == 0 && memcmp(a->dir, b->dir, sizeof a->dir) == 0);
  CU_ASSERT(a->file_type == b->file_type && a->nlabels == b->nlabels && strcmp(a->path, b->path) == 0);
  CU_ASSERT(memcmp(a->label_value, b->label_value, (size_t)a->nlabels * sizeof *a->label_value) == 0);
  CU_ASSERT(memcmp(a->label_count, b->label_count, (size_t)a->nlabels * sizeof *a->label_count) == 0);
  CU_ASSERT(memcmp(a->vox, b->vox, nvox) == 0);
  CU_ASSERT((a->vox_hi == NULL) == (b->vox_hi == NULL));
  if (a->vox_hi && b->vox_hi) CU_ASSERT(memcmp(a->vox_hi, b->vox_hi, nvox) == 0);
  CU_ASSERT((a->names == NULL) == (b->names == NULL));
  if (!a->names || !b->names) return;
  CU_ASSERT_FATAL(a->names->n == b->names->n);
  for (int64_t i = 0; i < a->names->n; i++) {
    CU_ASSERT(a->names->value[i] == b->names->value[i] && a->names->colour[i] == b->names->colour[i]);
    CU_ASSERT_STRING_EQUAL(a->names->name[i], b->names->name[i]);
  }
}

/* What a rank that did not read the file gets (i2m_dist_image_read): the description packed
 * and unpacked, the voxels copied as they are. */
static i2m_image_t *pack_round_trip(const i2m_image_t *img)
{
  void *buf = NULL;
  size_t len = 0;
  i2m_image_t *out = NULL;
  CU_ASSERT_FATAL(i2m_image_pack_meta(img, &buf, &len) == I2M_OK);
  CU_ASSERT_FATAL(i2m_image_unpack_meta(buf, len, &out) == I2M_OK);
  const size_t nvox = (size_t)(img->n[0] * img->n[1] * img->n[2]);
  memcpy(out->vox, img->vox, nvox);
  if (img->vox_hi && out->vox_hi) memcpy(out->vox_hi, img->vox_hi, nvox);
  i2m_image_t *cut = NULL; /* (a description cut short is refused) */
  CU_ASSERT(i2m_image_unpack_meta(buf, len - 8, &cut) != I2M_OK && cut == NULL);
  i2m_free(&buf);
  return out;
}

/* The knee atlas (names with colours) and an image of more than 255 labels (high bytes),
 * oblique, with a name holding spaces. */
static void test_pack_round_trip(void)
{
  char path[1024];
  i2m_image_t *img = NULL;
  snprintf(path, sizeof path, "%s/knee_atlas.nrrd", test_data_dir());
  CU_ASSERT_FATAL(i2m_image_read(path, &img) == I2M_OK);
  i2m_image_t *copy = pack_round_trip(img);
  assert_same_image(copy, img);
  i2m_image_destroy(&copy);
  i2m_image_destroy(&img);
  const int64_t n[3] = {7, 9, 11};
  const double sp[3] = {0.5, 0.75, 2.0}, org[3] = {-3.0, 1e7, 42.0};
  const double dir[9] = {0, 1, 0, -1, 0, 0, 0, 0, 1};
  int64_t *v = malloc(7 * 9 * 11 * sizeof *v);
  for (int64_t i = 0; i < 7 * 9 * 11; i++) v[i] = 1000 + i % 300;
  CU_ASSERT_FATAL(i2m_image_create_from_values(n, sp, org, dir, v, &img) == I2M_OK);
  free(v);
  CU_ASSERT_FATAL(img->vox_hi != NULL && img->nlabels == 301);
  CU_ASSERT_FATAL(image_names_create(2, &img->names) == I2M_OK);
  CU_ASSERT_FATAL(image_names_add(img->names, 1000, "a name with spaces", 18) == I2M_OK);
  CU_ASSERT_FATAL(image_names_add(img->names, 1299, "x", 1) == I2M_OK);
  img->names->colour[0] = 0x123456;
  copy = pack_round_trip(img);
  assert_same_image(copy, img);
  i2m_image_destroy(&copy);
  i2m_image_destroy(&img);
}

static void test_knee_atlas(void)
{
  char path[1024];
  i2m_image_t *img = NULL;
  snprintf(path, sizeof path, "%s/knee_atlas.nrrd", test_data_dir());
  CU_ASSERT_FATAL(i2m_image_read(path, &img) == I2M_OK);
  CU_ASSERT_FATAL(img->names != NULL);
  /* the table names 99 values; the image holds 49 tissues, of which label 3 is not named */
  CU_ASSERT(img->names->n == 48);
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 9), "infrapatellar_fat_body");
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 83), "femoral_cartilage");
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 98), "patella");
  CU_ASSERT(i2m_label_name(img->names, 3) == NULL);
  CU_ASSERT(i2m_label_name(img->names, 0) == NULL);
  for (int64_t i = 0; i < img->names->n; i++) { /* only labels present */
    int found = 0;
    for (int l = 1; l < img->nlabels; l++) found |= img->label_value[l] == img->names->value[i];
    CU_ASSERT(found);
  }
  i2m_image_destroy(&img);
  i2m_image_read_opts_t ro = {.header_only = true}; /* (no labels to name) */
  CU_ASSERT_FATAL(i2m_image_read_with(path, &ro, &img, NULL) == I2M_OK);
  CU_ASSERT(img->names == NULL);
  i2m_image_destroy(&img);
}

static void test_table_beside(void)
{
  write_small_image("a");
  write_text("a.ctbl", "# Color table file\n# 4 values\n0 Background 0 0 0 0\n5 left  kidney 10 20 30 255\r\n"
                       "\n7 vein 1 2 3 255\n9 absent 1 1 1 255\n");
  i2m_image_t *img = read_tmp("a.nrrd");
  CU_ASSERT_FATAL(img->names != NULL);
  CU_ASSERT(img->names->n == 3); /* 0, 5, 7: 9 is not in the image, 300 has no name */
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 0), "Background");
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 5), "left  kidney");
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 7), "vein");
  CU_ASSERT(i2m_label_name(img->names, 9) == NULL);
  CU_ASSERT(i2m_label_name(img->names, 300) == NULL);
  /* the colours go with the names (i2m-check's pictures use them): a name with spaces too */
  for (int64_t i = 0; i < img->names->n; i++) {
    const int64_t v = img->names->value[i];
    const int32_t want = v == 0 ? 0 : v == 5 ? (10 << 16 | 20 << 8 | 30) : (1 << 16 | 2 << 8 | 3);
    CU_ASSERT_EQUAL(img->names->colour[i], want);
  }
  i2m_image_destroy(&img);
  remove(tmp_path("a.nrrd"));
  remove(tmp_path("a.ctbl"));
}

static void test_table_malformed(void)
{
  static const char *bad[] = {
      "5 kidney 10 20 30\n",          /* a colour missing */
      "5 kidney 10 20 300 255\n",     /* out of range */
      "x kidney 10 20 30 255\n",      /* not a value */
      "5 kidney 1 2 3 4\n5 liver 1 2 3 4\n", /* named twice */
  };
  write_small_image("b");
  for (size_t k = 0; k < sizeof bad / sizeof *bad; k++) {
    write_text("b.ctbl", bad[k]);
    i2m_label_names_t *names = NULL;
    CU_ASSERT(image_names_read_ctbl(tmp_path("b.ctbl"), &names) == I2M_ERR_INPUT);
    CU_ASSERT(names == NULL);
    i2m_image_t *img = read_tmp("b.nrrd"); /* the read itself succeeds, without names */
    CU_ASSERT(img->names == NULL);
    CU_ASSERT(img->nlabels == 4);
    i2m_image_destroy(&img);
  }
  remove(tmp_path("b.ctbl"));
  i2m_image_t *img = read_tmp("b.nrrd"); /* no table at all */
  CU_ASSERT(img->names == NULL);
  i2m_image_destroy(&img);
  remove(tmp_path("b.nrrd"));
}

/* ---- 3D Slicer segmentations ---- */

#define SN 6 /* the segmentations are SN^3 voxels */

/* Writes a .seg.nrrd: @p layers layers (1: 3-D data), voxels v[voxel * layers + layer],
 * the header lines @p keys. */
static void write_seg(const char *name, int layers, const uint8_t *v, const char *keys)
{
  FILE *f = fopen(tmp_path(name), "wb");
  CU_ASSERT_FATAL(f != NULL);
  fprintf(f, "NRRD0004\ntype: unsigned char\nencoding: raw\nspace: left-posterior-superior\n");
  if (layers > 1)
    fprintf(f, "dimension: 4\nsizes: %d %d %d %d\nkinds: list domain domain domain\n"
               "space directions: none (2,0,0) (0,2,0) (0,0,2)\n", layers, SN, SN, SN);
  else
    fprintf(f, "dimension: 3\nsizes: %d %d %d\nspace directions: (2,0,0) (0,2,0) (0,0,2)\n", SN, SN, SN);
  fprintf(f, "space origin: (0,0,0)\nSegmentation_MasterRepresentation:=Binary labelmap\n%s\n", keys);
  fwrite(v, 1, (size_t)(SN * SN * SN * layers), f);
  fclose(f);
}

static int64_t count_of(const i2m_image_t *img, int64_t value)
{
  for (int l = 0; l < img->nlabels; l++)
    if (img->label_value[l] == value) return img->label_count[l];
  return -1;
}

static void test_seg_one_layer(void)
{
  uint8_t v[SN * SN * SN];
  for (int i = 0; i < SN * SN * SN; i++) v[i] = (uint8_t)(i < 50 ? 3 : i < 80 ? 8 : 0);
  write_seg("one.seg.nrrd", 1, v,
            "Segment0_ID:=Segment_1\nSegment0_Name:=femur\nSegment0_LabelValue:=3\nSegment0_Layer:=0\n"
            "Segment1_ID:=tibia_id\nSegment1_LabelValue:=8\nSegment1_Layer:=0\n"
            "Segment2_Name:=absent\nSegment2_LabelValue:=9\nSegment2_Layer:=0\n");
  i2m_image_t *img = read_tmp("one.seg.nrrd");
  CU_ASSERT(img->nlabels == 3);
  CU_ASSERT(count_of(img, 3) == 50 && count_of(img, 8) == 30);
  CU_ASSERT_FATAL(img->names != NULL);
  CU_ASSERT(img->names->n == 2);
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 3), "femur");
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 8), "tibia_id"); /* (no name: the ID) */
  CU_ASSERT(img->spacing[0] == 2.0 && img->n[0] == SN);
  i2m_image_destroy(&img);
  remove(tmp_path("one.seg.nrrd"));
}

/* Two layers whose segments share label value 1: renumbered 1, 2, 3 in segment order; the
 * voxels in both layers go to the lower layer's segment. */
static void test_seg_two_layers(void)
{
  const int nv = SN * SN * SN;
  uint8_t v[2 * SN * SN * SN];
  int64_t want[4] = {0, 0, 0, 0};
  for (int i = 0; i < nv; i++) {
    v[2 * i] = (uint8_t)(i < 100 ? 1 : i < 120 ? 2 : 0);  /* layer 0: skin (1), bone (2) */
    v[2 * i + 1] = (uint8_t)(i >= 90 && i < 150 ? 1 : 0); /* layer 1: tumour (1), overlaps 30 */
    want[v[2 * i] == 1 ? 2 : v[2 * i] == 2 ? 3 : v[2 * i + 1] ? 1 : 0]++;
  }
  write_seg("two.seg.nrrd", 2, v,
            "Segment0_Name:=tumour\nSegment0_LabelValue:=1\nSegment0_Layer:=1\n"
            "Segment1_Name:=skin\nSegment1_LabelValue:=1\nSegment1_Layer:=0\n"
            "Segment2_Name:=bone\nSegment2_LabelValue:=2\nSegment2_Layer:=0\n");
  i2m_image_t *img = read_tmp("two.seg.nrrd");
  CU_ASSERT(img->n[0] == SN && img->n[1] == SN && img->n[2] == SN);
  CU_ASSERT(img->nlabels == 4);
  CU_ASSERT(count_of(img, 0) == want[0]);
  CU_ASSERT(count_of(img, 1) == want[1] && want[1] == 30); /* tumour: 60 voxels, 30 under skin or bone */
  CU_ASSERT(count_of(img, 2) == want[2] && count_of(img, 3) == want[3]);
  CU_ASSERT_FATAL(img->names != NULL);
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 1), "tumour");
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 2), "skin");
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 3), "bone");
  for (int i = 0; i < nv; i++) { /* voxel by voxel */
    int64_t got = img->label_value[i2m_image_index(img, i)];
    int64_t exp = v[2 * i] == 1 ? 2 : v[2 * i] == 2 ? 3 : v[2 * i + 1] ? 1 : 0;
    CU_ASSERT(got == exp);
    if (got != exp) break;
  }
  i2m_image_destroy(&img);
  /* the header alone: the spatial size */
  i2m_image_read_opts_t ro = {.header_only = true};
  CU_ASSERT_FATAL(i2m_image_read_with(tmp_path("two.seg.nrrd"), &ro, &img, NULL) == I2M_OK);
  CU_ASSERT(img->n[0] == SN && img->n[1] == SN && img->n[2] == SN);
  i2m_image_destroy(&img);
  remove(tmp_path("two.seg.nrrd"));
}

/* Distinct label values across layers are kept as they are. */
static void test_seg_values_kept(void)
{
  const int nv = SN * SN * SN;
  uint8_t v[2 * SN * SN * SN];
  for (int i = 0; i < nv; i++) {
    v[2 * i] = (uint8_t)(i < 40 ? 4 : 0);
    v[2 * i + 1] = (uint8_t)(i >= 100 && i < 130 ? 9 : 0);
  }
  write_seg("kept.seg.nrrd", 2, v,
            "Segment0_Name:=a\nSegment0_LabelValue:=4\nSegment0_Layer:=0\n"
            "Segment1_Name:=b\nSegment1_LabelValue:=9\nSegment1_Layer:=1\n");
  i2m_image_t *img = read_tmp("kept.seg.nrrd");
  CU_ASSERT(img->nlabels == 3 && count_of(img, 4) == 40 && count_of(img, 9) == 30);
  CU_ASSERT_STRING_EQUAL(i2m_label_name(img->names, 9), "b");
  i2m_image_destroy(&img);
  remove(tmp_path("kept.seg.nrrd"));
}

static void test_cleanup(void)
{
  CU_ASSERT(rmdir(tmp_dir) == 0); /* every test removed its files */
}

static const test_case_t cases[] = {
    {"knee atlas: names of its .ctbl, labels present only", test_knee_atlas},
    {"an image's description packed and unpacked (names, colours, high bytes)", test_pack_round_trip},
    {"colour table beside an image: comments, spaces, CRLF", test_table_beside},
    {"malformed or missing table: no names, the read succeeds", test_table_malformed},
    {"segmentation, one layer: values kept, segment names", test_seg_one_layer},
    {"segmentation, two layers: renumbered, overlaps to the lower layer", test_seg_two_layers},
    {"segmentation, two layers: distinct values kept", test_seg_values_kept},
    {"scratch directory left empty", test_cleanup},
};

TEST_MAIN("image_names", cases)
