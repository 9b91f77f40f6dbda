/* libFuzzer harness: the image readers (NRRD, NIfTI-1, MetaImage, INR, gzip streams). */
#include "fuzz_common.h"
#include "i2m/image.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
  static const char *const exts[] = {".nrrd", ".nhdr", ".nii", ".nii.gz", ".hdr", ".mha", ".mhd", ".inr", ".inr.gz", ".img"};
  const char *path = fuzz_file(data, size, exts, sizeof exts / sizeof *exts);
  if (!path) return 0;
  i2m_image_t *img = NULL;
  if (i2m_image_read(path, &img) == I2M_OK) i2m_image_destroy(&img);
  remove(path);
  return 0;
}
