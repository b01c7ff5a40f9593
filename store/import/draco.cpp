/* store/import/draco.cpp - the thin C++ shim that reads Draco (.drc) meshes into st_mesh.
 *
 * Owns: st_draco_read_mem, st_draco_read_file. Uses draco/compression/decode.h only (the
 * mesh_utils and glTF headers need Eigen and tinygltf). Does not own: welding and seams
 * (mesh.c, seams.c).
 *
 * Mapping: positions = the POSITION attribute's values (Draco splits points where UVs split;
 * st_mesh_weld merges them again), uvs = the first TEX_COORD attribute's values, flipped into
 * texture space (v = 1 - v_file: .drc files made from OBJ keep OBJ's v-up convention).
 * Triangle corner k of face f -> the attribute value indices of its point. No TEX_COORD:
 * nuv = 0 and every corner ST_MESH_NO_UV (the importer then refuses with ST_ENOUV).
 * Counts are checked against the caps before the st_mesh is allocated; NaN or infinite
 * values are refused. No exception leaves this file.
 *
 * Before Draco decodes, the counts its connectivity header declares (faces, vertices, points)
 * are read here and checked against the caps: Draco sizes its corner table from them before
 * reading any face, so a 200-byte file declaring 2^28 faces made it allocate gigabytes (found
 * by tests/fuzz/fuzz_draco.c; the reproducer is in tests/fuzz/seeds/fuzz_draco/).
 */
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <vector>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wsign-compare"
#include <draco/compression/decode.h>
#include <draco/compression/point_cloud/point_cloud_decoder.h>
#include <draco/core/varint_decoding.h>
#include <draco/metadata/metadata_decoder.h>
#pragma GCC diagnostic pop

extern "C" {
#include "mesh.h"
#include "mesh_io.h"
#include "fileio.h"
}

namespace {

bool u32_at(draco::DecoderBuffer *b, bool varint, uint32_t *v)
{
    return varint ? draco::DecodeVarint(v, b) : b->Decode(v);
}

/* The counts a mesh's connectivity header declares, read the way Draco's own decoders read
 * them (point_cloud_decoder.cc, mesh_sequential_decoder.cc, mesh_edgebreaker_decoder*.cc), and
 * checked against the caps. A header it cannot read is left to Draco (which refuses it). */
int check_declared_counts(const void *buf, size_t len, uint32_t max_tris, uint32_t max_verts,
                          st_error *e)
{
    draco::DecoderBuffer b;
    b.Init(static_cast<const char *>(buf), len);
    draco::DracoHeader h;
    if (!draco::PointCloudDecoder::DecodeHeader(&b, &h).ok() ||
        h.encoder_type != draco::TRIANGULAR_MESH)
        return ST_OK;
    uint16_t ver = DRACO_BITSTREAM_VERSION(h.version_major, h.version_minor);
    b.set_bitstream_version(ver);
    if (ver >= DRACO_BITSTREAM_VERSION(1, 3) && (h.flags & METADATA_FLAG_MASK)) {
        draco::GeometryMetadata md;
        draco::MetadataDecoder mdd;
        if (!mdd.DecodeGeometryMetadata(&b, &md))
            return ST_OK;
    }
    uint64_t faces = 0, verts = 0, max_v = 0;
    if (h.encoder_method == draco::MESH_SEQUENTIAL_ENCODING) {
        uint32_t nf, np;
        bool v = ver >= DRACO_BITSTREAM_VERSION(2, 2);
        if (!u32_at(&b, v, &nf) || !u32_at(&b, v, &np))
            return ST_OK;
        faces = nf;
        verts = np;   /* points: the corners' distinct attribute combinations, plus any unused */
        max_v = (uint64_t)max_tris * 3 + max_verts;
    } else if (h.encoder_method == draco::MESH_EDGEBREAKER_ENCODING) {
        uint8_t traversal, nattr;
        uint32_t new_verts, nv, nf, nsym, nsplit;
        bool v = ver >= DRACO_BITSTREAM_VERSION(2, 0);
        if (!b.Decode(&traversal) ||
            (ver < DRACO_BITSTREAM_VERSION(2, 2) && !b.Decode(&new_verts)) ||
            !u32_at(&b, v, &nv) || !u32_at(&b, v, &nf) || !b.Decode(&nattr) ||
            !u32_at(&b, v, &nsym) || !u32_at(&b, v, &nsplit))
            return ST_OK;
        faces = nf;
        verts = (uint64_t)nv + nsplit;   /* every vertex is a corner of some face */
        max_v = faces * 3 + 3;
    } else {
        return ST_OK;
    }
    if (faces > max_tris || verts > max_v)
        return st_fail(e, ST_ETOOBIG, "Draco header declares %llu faces and %llu vertices: over "
                       "the cap of %u triangles", (unsigned long long)faces,
                       (unsigned long long)verts, max_tris);
    return ST_OK;
}

int read_impl(const void *buf, size_t len, const st_mesh_caps *caps, st_mesh **out, st_error *e)
{
    uint32_t max_tris = caps && caps->max_tris ? caps->max_tris : ST_MESH_MAX_TRIS;
    uint32_t max_verts = caps && caps->max_verts ? caps->max_verts : ST_MESH_MAX_VERTS;
    if (len < 5 || memcmp(buf, "DRACO", 5))
        return st_fail(e, ST_EFORMAT, "not a Draco file (no DRACO magic)");
    draco::DecoderBuffer db;
    db.Init(static_cast<const char *>(buf), len);
    auto type = draco::Decoder::GetEncodedGeometryType(&db);
    if (!type.ok())
        return st_fail(e, ST_EFORMAT, "Draco header: %.200s", type.status().error_msg());
    if (type.value() != draco::TRIANGULAR_MESH)
        return st_fail(e, ST_EUNSUPPORTED, "the Draco file holds a point cloud, not a mesh");
    int rc = check_declared_counts(buf, len, max_tris, max_verts, e);
    if (rc)
        return rc;
    draco::Decoder dec;
    auto res = dec.DecodeMeshFromBuffer(&db);
    if (!res.ok())
        return st_fail(e, ST_EFORMAT, "Draco decode: %.200s", res.status().error_msg());
    std::unique_ptr<draco::Mesh> dm = std::move(res).value();
    const draco::PointAttribute *pa = dm->GetNamedAttribute(draco::GeometryAttribute::POSITION);
    const draco::PointAttribute *ta = dm->GetNamedAttribute(draco::GeometryAttribute::TEX_COORD);
    if (!pa || pa->num_components() < 2)
        return st_fail(e, ST_EFORMAT, "Draco mesh without a position attribute");
    size_t nf = dm->num_faces(), np = pa->size(), nt = ta ? ta->size() : 0;
    if (nf == 0)
        return st_fail(e, ST_EFORMAT, "Draco mesh without faces");
    if (nf > max_tris || np > max_verts || nt > max_verts)
        return st_fail(e, ST_ETOOBIG, "Draco mesh of %zu faces, %zu positions, %zu uvs is over the caps",
                       nf, np, nt);
    st_mesh *m = nullptr;
    rc = st_mesh_alloc((uint32_t)np, (uint32_t)nt, (uint32_t)nf, &m, e);
    if (rc)
        return rc;
    for (size_t i = 0; i < np; i++) {
        float v[3] = {0, 0, 0};
        if (!pa->ConvertValue<float>(draco::AttributeValueIndex((uint32_t)i), 3, v) ||
            !std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2])) {
            st_mesh_free(m);
            return st_fail(e, ST_EFORMAT, "Draco position %zu is not a finite 3D value", i);
        }
        memcpy(&m->pos[i * 3], v, sizeof v);
    }
    for (size_t i = 0; i < nt; i++) {
        float v[2] = {0, 0};
        if (!ta->ConvertValue<float>(draco::AttributeValueIndex((uint32_t)i), 2, v) ||
            !std::isfinite(v[0]) || !std::isfinite(v[1])) {
            st_mesh_free(m);
            return st_fail(e, ST_EFORMAT, "Draco texture coordinate %zu is not finite", i);
        }
        m->uv[i * 2] = v[0];
        m->uv[i * 2 + 1] = 1.0f - v[1];
    }
    size_t npoints = dm->num_points();
    for (size_t f = 0; f < nf; f++) {
        const draco::Mesh::Face &F = dm->face(draco::FaceIndex((uint32_t)f));
        for (int k = 0; k < 3; k++) {
            if (F[k].value() >= npoints) {
                st_mesh_free(m);
                return st_fail(e, ST_EFORMAT, "Draco face %zu: point %u out of range", f, F[k].value());
            }
            uint32_t pi = pa->mapped_index(F[k]).value();
            if (pi >= np) {
                st_mesh_free(m);
                return st_fail(e, ST_EFORMAT, "Draco face %zu: position index out of range", f);
            }
            m->tri_pos[f * 3 + k] = pi;
            if (ta) {
                uint32_t ti = ta->mapped_index(F[k]).value();
                if (ti >= nt) {
                    st_mesh_free(m);
                    return st_fail(e, ST_EFORMAT, "Draco face %zu: uv index out of range", f);
                }
                m->tri_uv[f * 3 + k] = ti;
            } else {
                m->tri_uv[f * 3 + k] = ST_MESH_NO_UV;
            }
        }
        m->tri_face[f] = (uint32_t)f;
        if (!ta)
            m->ntri_nouv++;
    }
    m->nfaces_src = (uint32_t)nf;
    *out = m;
    return ST_OK;
}

} // namespace

extern "C" int st_draco_read_mem(const void *buf, size_t len, const st_mesh_caps *caps,
                                 st_mesh **out, st_error *e)
{
    *out = nullptr;
    try {
        return read_impl(buf, len, caps, out, e);
    } catch (const std::bad_alloc &) {
        return st_fail(e, ST_ENOMEM, "out of memory decoding a Draco mesh");
    } catch (...) {
        return st_fail(e, ST_EFORMAT, "the Draco decoder raised an exception");
    }
}

extern "C" int st_draco_read_file(const char *path, const st_mesh_caps *caps, st_mesh **out,
                                  st_error *e)
{
    *out = nullptr;
    size_t maxb = caps && caps->max_bytes ? caps->max_bytes : ((size_t)1 << 30);
    void *buf;
    size_t len;
    int rc = st_file_read(path, maxb, &buf, &len, e);
    if (rc)
        return rc;
    rc = st_draco_read_mem(buf, len, caps, out, e);
    free(buf);
    if (rc && e) {
        char tmp[ST_ERRMSG_LEN];
        snprintf(tmp, sizeof tmp, "%s", e->msg);
        st_fail(e, rc, "%.80s: %.160s", path, tmp);
    }
    return rc;
}
