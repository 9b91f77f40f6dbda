/* Image layer internals shared by the readers (not part of the public API): the byte stream
 * over a file with optional inflate (read_stream.c), the streaming voxel-to-label conversion
 * (read_voxels.c), header text helpers and geometry checks (read.c), and the entry points of
 * the format readers (read_nrrd.c, read_nifti.c, read_metaimage.c, read_inr.c). */
#ifndef I2M_IMAGE_IMPL_H
#define I2M_IMAGE_IMPL_H

#include "i2m/image.h"

#include <stdio.h>
#include <zlib.h>

/** Allocates an image of n voxels with identity geometry and uninitialised vox[] (no
 *  vox_hi[] yet); copies @p path for messages. */
i2m_err_t image_alloc(const char *path, const int64_t n[3], i2m_image_t **out);

/** Creates the plane of high bytes (zero) when the first index above 255 comes. */
i2m_err_t image_add_high_plane(i2m_image_t *img);

/** Stores label index idx at voxel i. */
static inline i2m_err_t image_store_index(i2m_image_t *img, int64_t i, unsigned idx)
{
  img->vox[i] = (uint8_t)idx;
  if (I2M_UNLIKELY(idx > 255u) && !img->vox_hi) I2M_CALL(image_add_high_plane(img));
  if (img->vox_hi) img->vox_hi[i] = (uint8_t)(idx >> 8);
  return I2M_OK;
}

/* ---- byte stream (read_stream.c) ------------------------------------------------------- */

/** Size of the stream's decoded and compressed buffers. */
#define IMAGE_CHUNK ((size_t)1 << 18)

/** Reads a file front to back, either as it is ("raw mode") or, from some offset on, through
 *  zlib's inflate ("gzip mode": gzip or zlib streams, several gzip members in a row).  Every
 *  error message starts with the stream's name. */
typedef struct {
  FILE *f;             /* owned */
  const char *name;    /* borrowed: the path as the user gave it, for messages */
  int64_t file_size;   /* bytes in the file */
  int64_t file_pos;    /* offset in the file of the next byte fread() will return */
  int gz;              /* 1 in gzip mode */
  int z_ready;         /* inflateInit2 done (z must be ended) */
  int z_end;           /* the last member ended cleanly */
  int z_truncated;     /* the file ended before the compressed stream did */
  z_stream z;
  unsigned char *in;   /* owned: [IMAGE_CHUNK] compressed input (gzip mode) */
  unsigned char *buf;  /* owned: [IMAGE_CHUNK] decoded bytes; buf[head..tail) not consumed */
  size_t head, tail;
  int64_t gz_out;      /* decoded bytes consumed since gzip mode began */
  int eof;             /* no more bytes will come */
  int allow_external;  /* a detached header may name a data file outside its directory */
  int header_only;     /* read the header and check the data's size, but not the voxels */
} image_stream_t;

/** Opens @p path for reading; names a missing file, a directory and an empty file in the
 *  message.  @p s is zeroed first; close it with image_stream_close() even on error. */
i2m_err_t image_stream_open(const char *path, image_stream_t *s);
/** Releases the stream's file and buffers; accepts a zeroed or closed stream. */
void image_stream_close(image_stream_t *s);
/** Raw mode: continues at byte @p offset of the file (leaves gzip mode). */
i2m_err_t image_stream_seek(image_stream_t *s, int64_t offset);
/** Decodes the rest of the file, from the current position, with inflate. */
i2m_err_t image_stream_begin_gzip(image_stream_t *s);
/** Makes at least @p n (<= IMAGE_CHUNK) bytes available if the stream holds that many;
 *  *p points at them and *avail says how many there are (fewer only at the end). */
i2m_err_t image_stream_peek(image_stream_t *s, size_t n, const unsigned char **p, size_t *avail);
/** Marks @p n bytes returned by image_stream_peek() as consumed. */
void image_stream_consume(image_stream_t *s, size_t n);
/** Copies up to @p n bytes; *got < n only at the end of the stream. */
i2m_err_t image_stream_read(image_stream_t *s, void *dst, size_t n, size_t *got);
/** Discards @p n bytes; *got < n only at the end of the stream. */
i2m_err_t image_stream_skip(image_stream_t *s, int64_t n, int64_t *got);
/** Reads one text line without its "\n" or "\r\n" into line[cap]; *len = -1 at the end of the
 *  stream.  A line longer than cap - 1 bytes or holding a NUL byte is an error. */
i2m_err_t image_stream_getline(image_stream_t *s, char *line, size_t cap, int64_t *len);
/** Raw mode: file offset of the next byte; gzip mode: decoded bytes consumed so far. */
int64_t image_stream_tell(const image_stream_t *s);
/** Gzip mode, after the voxels: decodes (and drops) what is left of the compressed stream so
 *  that its checksum is verified; a corrupt or cut-off end is an error. */
i2m_err_t image_stream_finish(image_stream_t *s);

/* ---- voxels -> label indices (read_voxels.c) -------------------------------------------- */

/** How the voxels are stored. */
typedef struct {
  i2m_scalar_t type;
  int big_endian;       /* byte order of multi-byte voxels */
  int scale;            /* 1: the label is slope * v + inter (NIfTI scl_slope/scl_inter) */
  double slope, inter;
} image_voxels_t;

/** Bytes of one voxel of type @p t. */
size_t image_scalar_size(i2m_scalar_t t);

/** Reads n0*n1*n2 voxels from the stream into img->vox as label indices and fills
 *  label_value, label_count, nlabels and file_type.  Streams: no copy of the file's voxels is
 *  kept.  A stream that ends early is an error naming the header's size and what was found. */
i2m_err_t image_read_voxels(image_stream_t *s, const image_voxels_t *vf, i2m_image_t *img);
/** The end of every reader: the voxels from @p data (the header's stream @p s or a detached
 *  data file's), then the stream's end; with s->header_only, nothing (img->vox freed). */
i2m_err_t image_read_body(image_stream_t *s, image_stream_t *data, const image_voxels_t *vf, i2m_image_t *img);

/** Before allocating: checks that the stream can hold the voxels the header announces
 *  (raw mode: the file's remaining bytes; gzip mode: the best deflate ratio). */
i2m_err_t image_check_data_size(const image_stream_t *s, const int64_t n[3], i2m_scalar_t t);

/** Formats "512x512x119 int16 (62390272 bytes)" into buf[cap]. */
const char *image_describe_size(const int64_t n[3], i2m_scalar_t t, char *buf, size_t cap);

/* ---- geometry and header text helpers (read.c) ------------------------------------------ */

/** Sets spacing, dir and origin from axis[c] = world (LPS) step along index axis c (read
 *  only; not const because C11 cannot pass a double[3][3] as const).  Checks
 *  finite values and non-zero steps; orthonormalises nearly orthogonal axes (|cos| < 1e-3)
 *  and rejects sheared ones. */
i2m_err_t image_set_geometry(i2m_image_t *img, double axis[3][3], const double origin[3]);
/** A spacing given as such in a header (MetaImage ElementSpacing, NRRD spacings, INR VX/VY/VZ,
 *  NIfTI pixdim) must be a positive number in every format: a flipped axis belongs in the
 *  direction matrix, and a negative spacing is refused rather than read as one. */
i2m_err_t image_check_spacing(const char *path, const char *field, int axis, double v);
/** Refuses geometry that cannot be meshed in doubles: spacings outside 1e-6 .. 1e6 mm, or an
 *  image so far from the world's origin that its coordinates keep fewer than 20 bits below
 *  the smallest spacing (beyond 2^32 voxels from it). */
i2m_err_t image_check_range(const i2m_image_t *img);

/** ASCII case-insensitive string equality. */
int image_streq(const char *a, const char *b);
/** Removes leading and trailing white space in place; returns the start. */
char *image_trim(char *s);
/** Parses exactly @p n white-space separated integers (all of @p text). */
int image_parse_ints(const char *text, int64_t *v, int n);
/** Parses exactly @p n white-space separated finite numbers (all of @p text). */
int image_parse_doubles(const char *text, double *v, int n);
/** Number of white-space separated words in @p text. */
int image_count_words(const char *text);
/** Directory part of @p path joined with @p file (unless file is absolute), into out[cap]. */
/** The path of a detached header's data file (relative names: to the header's directory).
 *  Unless @p allow_external, a data file outside the header's directory is refused: a header
 *  must not make any file on the machine come out as label values. */
i2m_err_t image_sibling_path(const char *path, const char *file, int allow_external, char *out, size_t cap);

/* ---- tissue names (names.c) ------------------------------------------------------------ */

/** An empty list with room for @p cap names. */
i2m_err_t image_names_create(int64_t cap, i2m_label_names_t **out);
/** Appends (value, the first @p len bytes of name); the caller made room. */
i2m_err_t image_names_add(i2m_label_names_t *names, int64_t value, const char *name, size_t len);
/** Reads a 3D Slicer colour table (lines "value name r g b a", '#' comments); a malformed
 *  line or a value named twice is an error naming the line. */
i2m_err_t image_names_read_ctbl(const char *path, i2m_label_names_t **out);
/** Drops the names of values the image does not hold. */
void image_names_keep_present(i2m_label_names_t *names, const i2m_image_t *img);
/** Unless the image has names: those of <stem>.ctbl beside @p path (the image file) when that
 *  table exists, kept for the labels present; a malformed table: one warning, no names. */
void image_attach_ctbl(i2m_image_t *img, const char *path);

/* ---- format readers: @p s is open at offset 0, in gzip mode when the whole file is
 *      compressed; each reader allocates *out and closes nothing ------------------------- */
i2m_err_t image_read_nrrd(image_stream_t *s, const char *path, i2m_image_t **out);
i2m_err_t image_read_nifti(image_stream_t *s, const char *path, i2m_image_t **out);
i2m_err_t image_read_metaimage(image_stream_t *s, const char *path, i2m_image_t **out);
i2m_err_t image_read_inr(image_stream_t *s, const char *path, i2m_image_t **out);

#endif
