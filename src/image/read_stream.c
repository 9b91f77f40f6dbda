/* Image layer: a byte stream over one file for the readers.  Raw mode hands out the file's
 * bytes; gzip mode runs them through zlib's inflate (gzip or zlib wrapper detected, several
 * gzip members in a row) one chunk at a time, so that no reader ever holds a whole file.
 * Errors name the file: missing, a directory, empty, unreadable, corrupt or cut-off gzip. */
#include "image_impl.h"

#include <errno.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>

/* Decoded bytes that image_stream_finish() inflates past the voxels to reach the checksum;
 * past this, trailing data is left unchecked. */
#define DRAIN_MAX ((int64_t)64 << 20)

i2m_err_t image_stream_open(const char *path, image_stream_t *s)
{
  struct stat st;
  memset(s, 0, sizeof *s);
  s->name = path;
  if (stat(path, &st) != 0) return I2M_ERROR(I2M_ERR_IO, "%s: %s", path, strerror(errno));
  I2M_CHECK(!S_ISDIR(st.st_mode), I2M_ERR_IO, "%s: is a directory, not an image file", path);
  I2M_CHECK(S_ISREG(st.st_mode), I2M_ERR_IO, "%s: not a regular file", path);
  I2M_CHECK(st.st_size > 0, I2M_ERR_INPUT, "%s: empty file", path);
  s->file_size = (int64_t)st.st_size;
  s->f = fopen(path, "rb");
  if (!s->f) return I2M_ERROR(I2M_ERR_IO, "%s: %s", path, strerror(errno));
  return i2m_malloc(IMAGE_CHUNK, 1, &s->buf);
}

static void end_gzip(image_stream_t *s)
{
  if (s->z_ready) inflateEnd(&s->z);
  s->z_ready = 0;
  s->gz = 0;
}

void image_stream_close(image_stream_t *s)
{
  if (!s) return;
  end_gzip(s);
  if (s->f) fclose(s->f);
  s->f = NULL;
  i2m_free(&s->in);
  i2m_free(&s->buf);
}

int64_t image_stream_tell(const image_stream_t *s)
{
  return s->gz ? s->gz_out : s->file_pos - (int64_t)(s->tail - s->head);
}

i2m_err_t image_stream_seek(image_stream_t *s, int64_t offset)
{
  end_gzip(s);
  I2M_CHECK(offset >= 0 && offset <= s->file_size, I2M_ERR_INPUT,
            "%s: data offset %lld lies outside the file (%lld bytes)", s->name, (long long)offset,
            (long long)s->file_size);
  if (fseeko(s->f, (off_t)offset, SEEK_SET) != 0)
    return I2M_ERROR(I2M_ERR_IO, "%s: cannot seek to byte %lld: %s", s->name, (long long)offset,
                     strerror(errno));
  s->file_pos = offset;
  s->head = s->tail = 0;
  s->eof = 0;
  return I2M_OK;
}

i2m_err_t image_stream_begin_gzip(image_stream_t *s)
{
  I2M_CALL(image_stream_seek(s, image_stream_tell(s)));
  if (!s->in) I2M_CALL(i2m_malloc(IMAGE_CHUNK, 1, &s->in));
  memset(&s->z, 0, sizeof s->z);
  int r = inflateInit2(&s->z, 15 + 32); /* zlib or gzip wrapper, detected */
  I2M_CHECK(r == Z_OK, I2M_ERR_MEMORY, "%s: cannot start zlib's inflate (%s)", s->name,
            s->z.msg ? s->z.msg : "out of memory");
  s->z_ready = 1;
  s->gz = 1;
  s->z_end = s->z_truncated = 0;
  s->gz_out = 0;
  return I2M_OK;
}

/* Appends file bytes to the compressed input; *got = 0 at the end of the file. */
static i2m_err_t read_input(image_stream_t *s, size_t *got)
{
  if (s->z.avail_in > 0 && s->z.next_in != s->in) memmove(s->in, s->z.next_in, s->z.avail_in);
  s->z.next_in = s->in;
  *got = fread(s->in + s->z.avail_in, 1, IMAGE_CHUNK - s->z.avail_in, s->f);
  if (*got == 0 && ferror(s->f))
    return I2M_ERROR(I2M_ERR_IO, "%s: read error: %s", s->name, strerror(errno));
  s->z.avail_in += (uInt)*got;
  s->file_pos += (int64_t)*got;
  return I2M_OK;
}

/* After the end of a compressed stream: another gzip member follows, or we are done
 * (anything else after the stream is ignored). */
static i2m_err_t next_member(image_stream_t *s)
{
  size_t got = 1;
  while (s->z.avail_in < 2 && got > 0) I2M_CALL(read_input(s, &got));
  if (s->z.avail_in >= 2 && s->z.next_in[0] == 0x1f && s->z.next_in[1] == 0x8b) {
    I2M_CHECK(inflateReset(&s->z) == Z_OK, I2M_ERR_INTERNAL, "%s: inflateReset failed", s->name);
    return I2M_OK;
  }
  s->z_end = 1;
  return I2M_OK;
}

/* Gzip mode: inflates into buf[tail..] until some bytes come out or the stream ends. */
static i2m_err_t fill_gzip(image_stream_t *s)
{
  while (s->tail < IMAGE_CHUNK) {
    if (s->z_end) {
      s->eof = 1;
      return I2M_OK;
    }
    if (s->z.avail_in == 0) {
      size_t got;
      I2M_CALL(read_input(s, &got));
      if (got == 0) { /* the file ended inside the compressed stream */
        s->z_truncated = 1;
        s->eof = 1;
        return I2M_OK;
      }
    }
    size_t room = IMAGE_CHUNK - s->tail;
    s->z.next_out = s->buf + s->tail;
    s->z.avail_out = (uInt)room;
    int r = inflate(&s->z, Z_NO_FLUSH);
    size_t made = room - s->z.avail_out;
    s->tail += made;
    if (r == Z_STREAM_END) {
      I2M_CALL(next_member(s));
    } else if (r == Z_DATA_ERROR || r == Z_NEED_DICT || r == Z_STREAM_ERROR) {
      return I2M_ERROR(I2M_ERR_INPUT, "%s: corrupt gzip data after %lld decompressed bytes (%s)",
                       s->name, (long long)(s->gz_out + (int64_t)s->tail),
                       s->z.msg ? s->z.msg : "invalid compressed data");
    } else if (r == Z_MEM_ERROR) {
      return I2M_ERROR(I2M_ERR_MEMORY, "%s: out of memory in zlib's inflate", s->name);
    }
    if (made > 0) return I2M_OK;
  }
  return I2M_OK;
}

/* Adds bytes at buf[tail..]; sets eof when none will come. */
static i2m_err_t fill(image_stream_t *s)
{
  if (s->gz) return fill_gzip(s);
  size_t room = IMAGE_CHUNK - s->tail;
  size_t got = fread(s->buf + s->tail, 1, room, s->f);
  if (got < room && ferror(s->f))
    return I2M_ERROR(I2M_ERR_IO, "%s: read error: %s", s->name, strerror(errno));
  if (got == 0) s->eof = 1;
  s->tail += got;
  s->file_pos += (int64_t)got;
  return I2M_OK;
}

i2m_err_t image_stream_peek(image_stream_t *s, size_t n, const unsigned char **p, size_t *avail)
{
  if (n > IMAGE_CHUNK) n = IMAGE_CHUNK;
  if (s->tail - s->head < n && !s->eof) {
    if (s->head > 0) { /* compact, so that n bytes fit */
      memmove(s->buf, s->buf + s->head, s->tail - s->head);
      s->tail -= s->head;
      s->head = 0;
    }
    while (s->tail < n && !s->eof) I2M_CALL(fill(s));
  }
  *p = s->buf + s->head;
  *avail = s->tail - s->head;
  return I2M_OK;
}

void image_stream_consume(image_stream_t *s, size_t n)
{
  I2M_ASSERT(n <= s->tail - s->head);
  s->head += n;
  if (s->gz) s->gz_out += (int64_t)n;
  if (s->head == s->tail) s->head = s->tail = 0;
}

i2m_err_t image_stream_read(image_stream_t *s, void *dst, size_t n, size_t *got)
{
  unsigned char *out = dst;
  *got = 0;
  while (*got < n) {
    const unsigned char *p;
    size_t avail;
    I2M_CALL(image_stream_peek(s, 1, &p, &avail));
    if (avail == 0) break;
    size_t k = n - *got < avail ? n - *got : avail;
    memcpy(out + *got, p, k);
    image_stream_consume(s, k);
    *got += k;
  }
  return I2M_OK;
}

i2m_err_t image_stream_skip(image_stream_t *s, int64_t n, int64_t *got)
{
  *got = 0;
  while (*got < n) {
    const unsigned char *p;
    size_t avail;
    I2M_CALL(image_stream_peek(s, 1, &p, &avail));
    if (avail == 0) break;
    size_t k = (uint64_t)(n - *got) < avail ? (size_t)(n - *got) : avail;
    image_stream_consume(s, k);
    *got += (int64_t)k;
  }
  return I2M_OK;
}

i2m_err_t image_stream_getline(image_stream_t *s, char *line, size_t cap, int64_t *len)
{
  size_t n = 0;
  int newline = 0;
  while (!newline) {
    const unsigned char *p;
    size_t avail;
    I2M_CALL(image_stream_peek(s, 1, &p, &avail));
    if (avail == 0) break;
    const unsigned char *nl = memchr(p, '\n', avail);
    size_t k = nl ? (size_t)(nl - p) : avail;
    I2M_CHECK(n + k < cap, I2M_ERR_INPUT,
              "%s: header line longer than %zu bytes (binary data where a header was expected?)",
              s->name, cap - 1);
    memcpy(line + n, p, k);
    n += k;
    image_stream_consume(s, nl ? k + 1 : k);
    newline = nl != NULL;
  }
  if (n == 0 && !newline) {
    line[0] = '\0';
    *len = -1;
    return I2M_OK;
  }
  I2M_CHECK(memchr(line, '\0', n) == NULL, I2M_ERR_INPUT,
            "%s: binary data where a header line was expected", s->name);
  if (n > 0 && line[n - 1] == '\r') n--;
  line[n] = '\0';
  *len = (int64_t)n;
  return I2M_OK;
}

i2m_err_t image_stream_finish(image_stream_t *s)
{
  if (!s->gz) return I2M_OK;
  int64_t drained = 0;
  while (drained < DRAIN_MAX) {
    const unsigned char *p;
    size_t avail;
    I2M_CALL(image_stream_peek(s, 1, &p, &avail));
    if (avail == 0) break;
    image_stream_consume(s, avail);
    drained += (int64_t)avail;
  }
  I2M_CHECK(!s->z_truncated, I2M_ERR_INPUT,
            "%s: truncated gzip stream (the file ends before the end of the compressed data)",
            s->name);
  return I2M_OK;
}
