/* Image layer: tissue names of label values (i2m_label_names_t).  The readers of the files
 * that carry names (.ctbl colour tables, 3D Slicer segmentations) fill it. */
#include "image_impl.h"

const char *i2m_label_name(const i2m_label_names_t *names, int64_t value)
{
  if (!names) return NULL;
  for (int64_t i = 0; i < names->n; i++)
    if (names->value[i] == value) return names->name[i];
  return NULL;
}

void i2m_label_names_destroy(i2m_label_names_t **names)
{
  if (!names || !*names) return;
  for (int64_t i = 0; i < (*names)->n; i++) i2m_free(&(*names)->name[i]);
  i2m_free(&(*names)->name);
  i2m_free(&(*names)->value);
  i2m_free(names);
}
