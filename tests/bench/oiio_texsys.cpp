// tests/bench/oiio_texsys.cpp - the OpenImageIO TextureSystem that bench_native compares
// seamtex against (oiio_texsys.h): a thin shim with extern "C". Bench-only code.
#include "oiio_texsys.h"

#include <OpenImageIO/imageio.h>
#include <OpenImageIO/texture.h>

#include <cstdio>
#include <memory>

using namespace OIIO;

struct bto_ts {
    TextureSystem *ts;
    TextureOpt     opt;
};

static TypeDesc dtype_of(unsigned dtype)
{
    switch (dtype) {
    case 0: return TypeDesc::UINT8;
    case 1: return TypeDesc::UINT16;
    case 2: return TypeDesc::HALF;
    default: return TypeDesc::FLOAT;
    }
}

extern "C" int bto_write_image(const char *path, uint32_t w, uint32_t h, unsigned nchan,
                               unsigned dtype, const void *pixels, char *err, size_t errcap)
{
    auto out = ImageOutput::create(path);
    if (!out) {
        std::snprintf(err, errcap, "%s: %s", path, OIIO::geterror().c_str());
        return -1;
    }
    ImageSpec spec((int)w, (int)h, (int)nchan, dtype_of(dtype));
    if (!out->open(path, spec) || !out->write_image(dtype_of(dtype), pixels) || !out->close()) {
        std::snprintf(err, errcap, "%s: %s", path, out->geterror().c_str());
        return -1;
    }
    return 0;
}

extern "C" bto_ts *bto_create(double max_mb, int max_files)
{
    bto_ts *t = new (std::nothrow) bto_ts;
    if (!t)
        return nullptr;
    t->ts = TextureSystem::create(false);
    t->ts->attribute("max_memory_MB", (float)max_mb);
    t->ts->attribute("max_open_files", max_files);
    t->ts->attribute("deduplicate", 0);
    t->opt.mipmode = TextureOpt::MipModeOneLevel;
    t->opt.interpmode = TextureOpt::InterpBilinear;
    t->opt.anisotropic = 1;
    t->opt.swrap = t->opt.twrap = TextureOpt::WrapClamp;
    return t;
}

extern "C" void bto_free(bto_ts *t)
{
    if (!t)
        return;
    TextureSystem::destroy(t->ts);
    delete t;
}

extern "C" void *bto_handle(bto_ts *t, const char *path)
{
    return t->ts->get_texture_handle(ustring(path));
}

extern "C" void *bto_thread(bto_ts *t)
{
    return t->ts->create_thread_info();
}

extern "C" void bto_thread_free(bto_ts *t, void *thread)
{
    if (thread)
        t->ts->destroy_thread_info((TextureSystem::Perthread *)thread);
}

extern "C" size_t bto_sample(bto_ts *t, void *thread, void *handle, const bto_query *q,
                             size_t n, int nchan, float *out)
{
    TextureOpt opt = t->opt;   // texture() may write into the options: one copy per batch
    size_t bad = 0;
    auto *th = (TextureSystem::Perthread *)thread;
    auto *h = (TextureSystem::TextureHandle *)handle;
    for (size_t i = 0; i < n; i++)
        if (!t->ts->texture(h, th, opt, q[i].s, q[i].t, q[i].dsdx, q[i].dtdx, q[i].dsdy,
                            q[i].dtdy, nchan, out + i * (size_t)nchan))
            bad++;
    return bad;
}

extern "C" uint64_t bto_stat(bto_ts *t, const char *name)
{
    long long v64 = 0;
    if (t->ts->getattribute(name, TypeDesc::INT64, &v64))
        return (uint64_t)v64;
    int v = 0;
    if (t->ts->getattribute(name, TypeDesc::INT, &v))
        return (uint64_t)v;
    return 0;
}

extern "C" void bto_error(bto_ts *t, char *err, size_t errcap)
{
    std::string s = t->ts->geterror();
    if (!s.empty())
        std::snprintf(err, errcap, "%s", s.c_str());
}
