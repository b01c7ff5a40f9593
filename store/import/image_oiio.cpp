/* store/import/image_oiio.cpp - the thin C++ shim between seamtex and OpenImageIO 2.4.
 *
 * Owns: st_image_read (any format OIIO reads; refuses truncated PNGs and TIFFs without
 * BitsPerSample, which OIIO 2.4 misreads silently), st_image_write, st_image_read_any (EXR by
 * magic goes to exr.c), st_image_free, st_image_bytes. Does not own: EXR decoding (exr.c),
 * texture sets (import.c). Nothing here is on a hot path: one call per file.
 *
 * Every size from the file header (width, height, channels, format) is checked against the
 * caps with overflow-safe arithmetic before the texel buffer is allocated. No C++ exception
 * escapes into C: every entry point catches everything.
 */
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <string>
#include <vector>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <OpenImageIO/imageio.h>
#pragma GCC diagnostic pop

extern "C" {
#include "exr.h"
#include "image.h"
#include "set.h"
#include "image_io.h"
}

namespace {

using OIIO::ImageInput;
using OIIO::ImageOutput;
using OIIO::ImageSpec;
using OIIO::TypeDesc;

uint32_t cap_dim(const st_image_caps *c) { return c && c->max_dim ? c->max_dim : ST_MAX_DIM; }
size_t cap_bytes(const st_image_caps *c) { return c && c->max_bytes ? c->max_bytes : ((size_t)2 << 30); }

/* OIIO format -> the st_dtype kept in memory. Signed 8/16-bit data (a TIFF with
 * SampleFormat=INT: normal or height maps) becomes float, OIIO's -1..1 normalisation: read as
 * u8/u16 its negative half was clamped to 0, a silent wrong answer. */
unsigned pick_dtype(TypeDesc t)
{
    switch (t.basetype) {
    case TypeDesc::UINT8: return ST_DT_U8;
    case TypeDesc::UINT16: return ST_DT_U16;
    case TypeDesc::HALF: return ST_DT_HALF;
    default: return ST_DT_F32;
    }
}
TypeDesc oiio_type(unsigned dtype)
{
    switch (dtype) {
    case ST_DT_U8: return TypeDesc::UINT8;
    case ST_DT_U16: return TypeDesc::UINT16;
    case ST_DT_HALF: return TypeDesc::HALF;
    default: return TypeDesc::FLOAT;
    }
}

int find_chan(const ImageSpec &sp, const char *name)
{
    for (int i = 0; i < sp.nchannels && i < (int)sp.channelnames.size(); i++)
        if (sp.channelnames[i] == name)
            return i;
    return -1;
}

const char *ext_of(const char *path)
{
    const char *dot = strrchr(path, '.');
    const char *slash = strrchr(path, '/');
    return dot && (!slash || dot > slash) ? dot + 1 : "";
}

/* An OpenImageIO message as one line: libpng and others leave several lines ("PNG read error:
 * Not enough image data\nPNG library error"), which broke the daemon's one-line log records
 * and the protocol's message. Line breaks and other control bytes become "; " / a space. */
std::string one_line(std::string m)
{
    while (!m.empty() && (m.back() == '\n' || m.back() == '\r' || m.back() == ' '))
        m.pop_back();
    std::string o;
    for (char ch : m) {
        if (ch == '\n')
            o += "; ";
        else if ((unsigned char)ch < 0x20 || ch == 0x7f)
            o += ' ';
        else
            o += ch;
    }
    return o;
}

/* A PNG's chunk list must reach IEND inside the file. Checked before OIIO sees the file:
 * OIIO 2.4's PNG read callback builds a std::string and libpng then longjmps over it when the
 * file ends early, which leaks on every truncated upload. Returns 0 when fine or not a PNG. */
int png_truncated(FILE *f)
{
    unsigned char h[8];
    if (fread(h, 1, 8, f) != 8 || memcmp(h, "\x89PNG\r\n\x1a\n", 8))
        return 0;
    if (fseek(f, 0, SEEK_END))
        return 1;
    long size = ftell(f);
    long pos = 8;
    for (int n = 0; n < (1 << 24); n++) {
        if (pos + 8 > size || fseek(f, pos, SEEK_SET) || fread(h, 1, 8, f) != 8)
            return 1;
        uint32_t len = (uint32_t)h[0] << 24 | (uint32_t)h[1] << 16 | (uint32_t)h[2] << 8 | h[3];
        if (len > 0x7fffffffu || pos + 12 + (long)len > size)
            return 1;
        if (!memcmp(h + 4, "IEND", 4))
            return 0;
        pos += 12 + (long)len;
    }
    return 1;
}

/* A classic TIFF whose first directory has no BitsPerSample tag (258) means 1 bit per sample
 * by the TIFF default (Pillow writes its 1-bit images so); OIIO 2.4 takes 8 bits, reads past
 * the strip and returns made-up texels with no error. Such a file is refused before OIIO sees
 * it. Returns 1 for such a file, 0 when fine, not a classic TIFF, or unreadable here (OIIO
 * then reports what it finds). */
int tiff_without_bits_per_sample(FILE *f)
{
    unsigned char h[8];
    if (fseek(f, 0, SEEK_SET) || fread(h, 1, 8, f) != 8)
        return 0;
    bool le = !memcmp(h, "II*\0", 4), be = !memcmp(h, "MM\0*", 4);
    if (!le && !be)
        return 0;
    auto u16 = [le](const unsigned char *p) {
        return (unsigned)(le ? p[0] | p[1] << 8 : p[0] << 8 | p[1]);
    };
    uint32_t ifd = le ? (uint32_t)h[4] | (uint32_t)h[5] << 8 | (uint32_t)h[6] << 16 | (uint32_t)h[7] << 24
                      : (uint32_t)h[4] << 24 | (uint32_t)h[5] << 16 | (uint32_t)h[6] << 8 | h[7];
    unsigned char c[2];
    if (fseek(f, (long)ifd, SEEK_SET) || fread(c, 1, 2, f) != 2)
        return 0;
    unsigned n = u16(c);
    for (unsigned k = 0; k < n; k++) {
        unsigned char t[12];
        if (fread(t, 1, 12, f) != 12)
            return 0;
        if (u16(t) == 258)
            return 0;
    }
    return n > 0;
}

/* Reads channels [chb, che) of subimage 0, level 0 into dst (rows of rowbytes) in bands of
 * about 16 MiB (whole tile rows for a tiled file), stopping at the first band that fails or
 * leaves a message (libjpeg's "Premature end of JPEG file" returns success with one). OIIO's
 * read_image goes on through every row of a file that ends early, collecting a message per
 * row: a 200-byte TIFF declaring 20000 x 20000 RGB took 12 s and 1.4 GB before its refusal
 * (with the daemon's 8 GiB set cap, an upload of a few bytes could take the memory of several
 * such sets). Returns what the failing (or last) read returned; msg holds the reader's
 * message, empty when there was none. */
bool read_banded(ImageInput *in, const ImageSpec &sp, int chb, int che, TypeDesc t, uint8_t *dst,
                 size_t rowbytes, std::string &msg)
{
    int band = (int)(((size_t)16 << 20) / (rowbytes ? rowbytes : 1));
    if (band < 1)
        band = 1;
    if (sp.tile_width > 0 && sp.tile_height > 0)
        band = (band + sp.tile_height - 1) / sp.tile_height * sp.tile_height;
    for (int y = 0; y < sp.height; y += band) {
        int y1 = sp.height - y < band ? sp.height : y + band;
        uint8_t *at = dst + (size_t)y * rowbytes;
        bool ok = sp.tile_width > 0
                      ? in->read_tiles(0, 0, sp.x, sp.x + sp.width, sp.y + y, sp.y + y1, sp.z,
                                       sp.z + (sp.depth > 0 ? sp.depth : 1), chb, che, t, at)
                      : in->read_scanlines(0, 0, sp.y + y, sp.y + y1, sp.z, chb, che, t, at);
        msg = one_line(in->geterror());
        if (!ok || !msg.empty())
            return ok; /* a message with true: the caller refuses the file all the same */
    }
    return true;
}

int read_impl(const char *path, const st_image_caps *caps, st_image *out, st_error *e)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return st_fail(e, ST_ENOTFOUND, "%s: cannot open", path);
    int trunc = png_truncated(f);
    int nobps = trunc ? 0 : tiff_without_bits_per_sample(f);
    fclose(f);
    if (trunc)
        return st_fail(e, ST_EFORMAT, "%s: truncated PNG (its chunks do not reach IEND)", path);
    if (nobps)
        return st_fail(e, ST_EUNSUPPORTED, "%s: a TIFF without a BitsPerSample tag (1 bit per "
                       "sample by default) is not read: OpenImageIO 2.4 would take it as 8-bit "
                       "and make texels up; write the tag", path);
    /* keep alpha unassociated, as stored: texels are data, not pre-composited colour */
    ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = ImageInput::open(path, &config);
    if (!in) {
        std::string msg = one_line(OIIO::geterror());
        return st_fail(e, ST_EFORMAT, "%s: not an image OpenImageIO reads (%.160s)", path,
                       msg.c_str());
    }
    const ImageSpec &sp = in->spec();
    if (sp.width <= 0 || sp.height <= 0 || sp.nchannels <= 0 || sp.depth > 1)
        return st_fail(e, ST_EFORMAT, "%s: bad size %dx%dx%d with %d channels", path, sp.width,
                       sp.height, sp.depth, sp.nchannels);
    if ((uint32_t)sp.width > cap_dim(caps) || (uint32_t)sp.height > cap_dim(caps))
        return st_fail(e, ST_ETOOBIG, "%s: %dx%d is over the %u per-axis cap", path, sp.width,
                       sp.height, cap_dim(caps));
    /* channels: R,G,B,A by name when there are more than 4, else the first ones */
    int sel[4], nsel = 0;
    int alpha = -1;
    if (sp.nchannels > 4) {
        const char *names[4] = {"R", "G", "B", "A"};
        for (int i = 0; i < 4; i++) {
            int c = find_chan(sp, names[i]);
            if (c >= 0) {
                if (i == 3)
                    alpha = nsel;
                sel[nsel++] = c;
            }
        }
        if (nsel == 0)
            for (int i = 0; i < 4; i++)
                sel[nsel++] = i;
    } else {
        for (int i = 0; i < sp.nchannels; i++)
            sel[nsel++] = i;
        /* the alpha OIIO reports, never a guess from the count: a 2-channel TIFF (R, G: a
         * normal or flow map) or an RGB TIFF with an unspecified extra sample has none, and
         * calling its last channel alpha made INFO say alpha + premultiplied and COMPRESS
         * punch BC1 holes where that channel is under 0.5 */
        alpha = sp.alpha_channel >= 0 && sp.alpha_channel < sp.nchannels ? sp.alpha_channel : -1;
    }
    unsigned dt = pick_dtype(sp.format);
    size_t bytes = st_image_bytes((uint32_t)sp.width, (uint32_t)sp.height, (unsigned)nsel, dt, caps);
    size_t full = st_image_bytes((uint32_t)sp.width, (uint32_t)sp.height, (unsigned)sp.nchannels,
                                 dt, caps);
    if (!bytes || !full)
        return st_fail(e, ST_ETOOBIG, "%s: %dx%d x %d channels is over the %zu byte cap", path,
                       sp.width, sp.height, sp.nchannels, cap_bytes(caps));
    void *data = malloc(bytes);
    if (!data)
        return st_fail(e, ST_ENOMEM, "%s: out of memory for %zu bytes", path, bytes);
    bool contiguous = true;
    for (int i = 0; i < nsel; i++)
        if (sel[i] != sel[0] + i)
            contiguous = false;
    bool ok;
    std::string msg;
    size_t tsz = st_dtype_size(dt);
    if (contiguous) {
        ok = read_banded(in.get(), sp, sel[0], sel[0] + nsel, oiio_type(dt), (uint8_t *)data,
                         (size_t)sp.width * (size_t)nsel * tsz, msg);
    } else {
        void *tmp = malloc(full);
        if (!tmp) {
            free(data);
            return st_fail(e, ST_ENOMEM, "%s: out of memory for %zu bytes", path, full);
        }
        ok = read_banded(in.get(), sp, 0, sp.nchannels, oiio_type(dt), (uint8_t *)tmp,
                         (size_t)sp.width * (size_t)sp.nchannels * tsz, msg);
        if (ok) {
            size_t npx = (size_t)sp.width * sp.height;
            for (size_t p = 0; p < npx; p++)
                for (int c = 0; c < nsel; c++)
                    memcpy((uint8_t *)data + (p * nsel + c) * tsz,
                           (uint8_t *)tmp + (p * sp.nchannels + sel[c]) * tsz, tsz);
        }
        free(tmp);
    }
    /* A reader that hits truncated or corrupt data may still return true: libjpeg, for one,
     * fills the missing part with grey and OIIO keeps "Premature end of JPEG file" in the
     * input's error state (has_error() stays false). Any message left by the read refuses
     * the file: a texture that is partly made up is a silent wrong answer. */
    if (!ok || !msg.empty()) {
        free(data);
        return st_fail(e, ST_EFORMAT, "%s: %s: %.160s", path,
                       ok ? "truncated or corrupt (the reader reported it)" : "read failed",
                       msg.empty() ? "no reason given" : msg.c_str());
    }
    memset(out, 0, sizeof *out);
    out->w = (uint32_t)sp.width;
    out->h = (uint32_t)sp.height;
    out->nchan = (uint8_t)nsel;
    out->dtype = (uint8_t)dt;
    out->alpha_chan = (int8_t)alpha;
    out->data = data;
    std::string cs = sp.get_string_attribute("oiio:ColorSpace");
    std::string fmt = in->format_name();
    /* stored premultiplied: EXR (OpenEXR's convention; the DWAA/DWAB fallback) and a TIFF whose
     * alpha is associated (OIIO marks unassociated alpha it kept with oiio:UnassociatedAlpha) */
    out->premultiplied = alpha >= 0 && (fmt == "openexr" ||
                                        (fmt == "tiff" && !sp.get_int_attribute("oiio:UnassociatedAlpha", 0)));
    if (dt == ST_DT_HALF || dt == ST_DT_F32 || fmt == "hdr" || fmt == "openexr")
        out->colorspace = ST_CS_LINEAR;
    else if (cs == "Linear" || cs == "linear")
        out->colorspace = ST_CS_LINEAR;
    else
        out->colorspace = ST_CS_SRGB;
    std::string tf = sp.get_string_attribute("textureformat");
    out->envmap = tf == "CubeFace Environment" ? ST_ENVMAP_CUBE
                  : tf == "LatLong Environment" ? ST_ENVMAP_LATLONG : ST_ENVMAP_NONE;
    int nmip = 1;
    while (nmip < 64 && in->seek_subimage(0, nmip))
        nmip++;
    out->nlevels_file = (uint8_t)nmip;
    in->close();
    (void)in->geterror(); /* seek_subimage past the last level leaves a message: drop it */
    return ST_OK;
}

int write_impl(const char *path, uint32_t w, uint32_t h, unsigned nchan, unsigned dtype,
               const void *data, int envmap, int colorspace, int alpha, st_error *e)
{
    if (!w || !h || w > ST_MAX_DIM || h > ST_MAX_DIM || nchan < 1 || nchan > 4 ||
        !st_dtype_size(dtype))
        return st_fail(e, ST_EINVAL, "%s: cannot write %ux%u x %u channels of type %u", path, w,
                       h, nchan, dtype);
    std::string ext = ext_of(path);
    for (auto &ch : ext)
        ch = (char)tolower((unsigned char)ch);
    if (ext == "dds")
        return st_fail(e, ST_EUNSUPPORTED, "%s: OpenImageIO cannot write DDS (use bc1.h)", path);
    auto outp = ImageOutput::create(path);
    if (!outp) {
        std::string msg = one_line(OIIO::geterror()); /* also clears OIIO's pending per-thread message */
        return st_fail(e, ST_EUNSUPPORTED, "%s: no writer for this extension (%.120s)", path,
                       msg.c_str());
    }
    TypeDesc ft = oiio_type(dtype);
    if ((ext == "png" || ext == "jpg" || ext == "jpeg") && (dtype == ST_DT_HALF || dtype == ST_DT_F32))
        ft = ext == "png" ? TypeDesc::UINT16 : TypeDesc::UINT8;
    if ((ext == "jpg" || ext == "jpeg") && dtype == ST_DT_U16)
        ft = TypeDesc::UINT8;
    ImageSpec spec((int)w, (int)h, (int)nchan, ft);
    if (envmap == ST_ENVMAP_CUBE)       /* OpenEXR's writer turns it into envmap=cube */
        spec.attribute("textureformat", "CubeFace Environment");
    else if (envmap == ST_ENVMAP_LATLONG)
        spec.attribute("textureformat", "LatLong Environment");
    if (colorspace == ST_CS_LINEAR)
        spec.attribute("oiio:ColorSpace", "Linear");
    else if (colorspace == ST_CS_SRGB)
        spec.attribute("oiio:ColorSpace", "sRGB");
    /* alpha as the image says; PNG has no 2- or 4-channel form without one. A grey + alpha
     * image goes to EXR as Y, A (OIIO's default names R, G uploaded back without alpha) */
    if (ext == "png" && (nchan == 4 || nchan == 2))
        alpha = (int)nchan - 1;
    spec.alpha_channel = alpha >= 0 && alpha < (int)nchan ? alpha : -1;
    if (ext == "exr" && nchan == 2 && spec.alpha_channel == 1)
        spec.channelnames = {"Y", "A"};
    spec.attribute("oiio:UnassociatedAlpha", 1); /* write texels as given */
    /* A file written here is a function of its image (FETCH is byte-stable, PROTOCOL.md 4.10):
     * OpenImageIO 2.4's EXR writer stamps a file it is given no "DateTime" with the local wall
     * clock as `capDate`. No date belongs to the image, so the date given is empty: the header
     * keeps a capDate of length 0 (iinfo shows none). Any way to drop the attribute whole (a
     * DateTime of another type, a null string) makes the writer print an "OIIO DEBUG" line on
     * stderr for every file with Ubuntu's build. test_export checks the bytes under two clocks. */
    if (ext == "exr")
        spec.attribute("DateTime", "");
    if (!outp->open(path, spec)) {
        std::string msg = one_line(outp->geterror());
        return st_fail(e, ST_EIO, "%s: cannot open for writing: %.160s", path, msg.c_str());
    }
    bool ok = outp->write_image(oiio_type(dtype), data);
    ok = outp->close() && ok;
    if (!ok) {
        std::string msg = one_line(outp->geterror());
        return st_fail(e, ST_EIO, "%s: write failed: %.160s", path, msg.c_str());
    }
    return ST_OK;
}

} // namespace

extern "C" int st_image_read(const char *path, const st_image_caps *caps, st_image *out,
                             st_error *e)
{
    /* an error leaves *out empty (no data), as st_exr_read does: st_image_free on it is safe
     * (fuzz_image found the error paths left the caller's struct as it was) */
    memset(out, 0, sizeof *out);
    try {
        return read_impl(path, caps, out, e);
    } catch (const std::bad_alloc &) {
        return st_fail(e, ST_ENOMEM, "%s: out of memory in OpenImageIO", path);
    } catch (...) {
        return st_fail(e, ST_EFORMAT, "%s: OpenImageIO raised an exception", path);
    }
}

extern "C" int st_image_read_any(const char *path, const st_image_caps *caps, st_image *out,
                                 st_error *e)
{
    unsigned char head[4] = {0, 0, 0, 0};
    memset(out, 0, sizeof *out);
    FILE *f = fopen(path, "rb");
    if (!f)
        return st_fail(e, ST_ENOTFOUND, "%s: cannot open", path);
    size_t n = fread(head, 1, 4, f);
    fclose(f);
    if (st_exr_is_magic(head, n)) {
        st_error ee;
        st_error_clear(&ee);
        int rc = st_exr_read(path, caps, out, &ee);
        if (rc != ST_EUNSUPPORTED) {
            if (rc && e)
                *e = ee;
            return rc;
        }
        /* a compression the OpenEXR 3.1 C API does not decode (DWAA/DWAB): OIIO's reader. When
         * that fails too, the C API's reason stays first and its code (UNSUPPORTED): a deep
         * file was refused with OIIO's "read_native_scanlines without an open file". */
        st_error oe;
        st_error_clear(&oe);
        rc = st_image_read(path, caps, out, &oe);
        if (rc == ST_OK)
            return ST_OK;
        if (rc == ST_ENOMEM) {
            if (e)
                *e = oe;
            return rc;
        }
        size_t pl = strlen(path);
        const char *why = !strncmp(oe.msg, path, pl) && !strncmp(oe.msg + pl, ": ", 2)
                              ? oe.msg + pl + 2 : oe.msg;
        return st_fail(e, ST_EUNSUPPORTED, "%.160s (OpenImageIO: %.90s)", ee.msg, why);
    }
    return st_image_read(path, caps, out, e);
}

extern "C" int st_image_write(const char *path, uint32_t w, uint32_t h, unsigned nchan,
                              unsigned dtype, const void *data, st_error *e)
{
    try {
        return write_impl(path, w, h, nchan, dtype, data, ST_ENVMAP_NONE, -1,
                          nchan == 4 || nchan == 2 ? (int)nchan - 1 : -1, e);
    } catch (const std::bad_alloc &) {
        return st_fail(e, ST_ENOMEM, "%s: out of memory in OpenImageIO", path);
    } catch (...) {
        return st_fail(e, ST_EIO, "%s: OpenImageIO raised an exception", path);
    }
}

extern "C" int st_image_write_img(const char *path, const st_image *img, st_error *e)
{
    try {
        return write_impl(path, img->w, img->h, img->nchan, img->dtype, img->data, img->envmap,
                          img->colorspace, img->alpha_chan, e);
    } catch (const std::bad_alloc &) {
        return st_fail(e, ST_ENOMEM, "%s: out of memory in OpenImageIO", path);
    } catch (...) {
        return st_fail(e, ST_EIO, "%s: OpenImageIO raised an exception", path);
    }
}
