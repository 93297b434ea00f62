// OpenVDB side of the bridge: see vdb_bridge.h and src/vdb/ffi.rs.
#include "vdbphoton/cpp/vdb_bridge.h"
#include "vdbphoton/src/vdb/ffi.rs.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/Archive.h>
#include <openvdb/io/DelayedLoadMetadata.h>
#include <openvdb/io/File.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/math/Maps.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cstring>
#include <istream>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace vdbphoton {
namespace ffi {

namespace {

using openvdb::Coord;
using openvdb::Index64;

// OpenVDB's registries, once. `__delayedload` metadata is unregistered:
// its reader (`io::DelayedLoadMetadata::readValue`) sizes vectors from
// counts in the file and decompresses Blosc data on the strength of its
// header alone, and it serves only delayed loading, which vdbphoton never
// uses. Unregistered, it is read as the raw bytes its stored size names
// (and dropped, as a "__" type), which `vdb::check` has bounded. Writing
// is unaffected (the writer builds that metadata itself).
void ensure_initialized() {
    static std::once_flag flag;
    std::call_once(flag, [] {
        openvdb::initialize();
        openvdb::io::DelayedLoadMetadata::unregisterType();
    });
}

// A read-only stream over bytes already in memory (and already checked by
// `vdb::check`): OpenVDB parses exactly the bytes Rust walked, never the
// file itself, which might have changed since.
class MemoryBuf : public std::streambuf {
public:
    MemoryBuf(const uint8_t* data, size_t size) {
        char* p = const_cast<char*>(reinterpret_cast<const char*>(data));
        setg(p, p, p + size);
    }

protected:
    pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode which) override {
        if (!(which & std::ios_base::in)) return pos_type(off_type(-1));
        const off_type size = egptr() - eback();
        off_type base = dir == std::ios_base::beg ? 0 : dir == std::ios_base::cur ? gptr() - eback() : size;
        off_type to = 0;
        if (__builtin_add_overflow(base, off, &to) || to < 0 || to > size) return pos_type(off_type(-1));
        setg(eback(), eback() + to, egptr());
        return pos_type(to);
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode which) override {
        return seekoff(off_type(pos), std::ios_base::beg, which);
    }
};

// Tags a stream as io::File::open does (seekable, so leaves use the value
// mask read with the topology), with the file's format and library version.
struct TaggedStream {
    MemoryBuf buf;
    std::istream is;
    openvdb::io::StreamMetadata::Ptr meta;
    TaggedStream(rust::Slice<const uint8_t> bytes, const StreamVersion& v)
        : buf(bytes.data(), bytes.size()), is(&buf), meta(new openvdb::io::StreamMetadata) {
        ensure_initialized();
        meta->setSeekable(true);
        openvdb::io::setStreamMetadataPtr(is, meta, /*transfer=*/false);
        openvdb::io::setVersion(is, openvdb::VersionId(v.library_major, v.library_minor), v.file_version);
    }
    ~TaggedStream() { openvdb::io::clearStreamMetadataPtr(is); }
    // OpenVDB read exactly the bytes the Rust walk accounted for.
    void expect_consumed(size_t n, const char* what) {
        const auto at = is.tellg();
        if (!is.good() || at < 0 || static_cast<size_t>(at) != n) {
            std::ostringstream m;
            m << "OpenVDB read " << static_cast<long long>(at) << " bytes of " << what << " where the check accounted for "
              << n;
            throw std::runtime_error(m.str());
        }
    }
};

// io::Archive::readGrid (compression flags, metadata, transform, topology,
// buffers) is a protected static member.
struct ArchiveReader : openvdb::io::Archive {
    static void read(openvdb::GridBase::Ptr grid, const openvdb::io::GridDescriptor& gd, std::istream& is) {
        openvdb::io::Archive::readGrid(grid, gd, is);
    }
};

std::string to_std(rust::Str s) { return std::string(s.data(), s.size()); }

// OpenVDB opened without delayed loading: with delayed loading a corrupt data
// block can crash later inside a lazy read (see shared/REFERENCE.md), without
// it OpenVDB reads each grid fully and reports damage as an exception.
struct OpenFile {
    openvdb::io::File file;
    explicit OpenFile(const std::string& path) : file(path) {
        ensure_initialized();
        file.open(/*delayLoad=*/false);
    }
    ~OpenFile() {
        try {
            if (file.isOpen()) file.close();
        } catch (...) {
        }
    }
};

std::string meta_value_string(const openvdb::Metadata& m) { return m.str(); }

rust::Vec<MetaEntry> collect_meta(const openvdb::MetaMap& map) {
    rust::Vec<MetaEntry> out;
    for (auto it = map.beginMeta(); it != map.endMeta(); ++it) {
        MetaEntry e;
        e.name = it->first;
        e.type_name = it->second->typeName();
        e.value = meta_value_string(*it->second);
        out.push_back(std::move(e));
    }
    return out;
}

// world = A * index + t, written as 3 rows of 4 (row-major, column-vector
// convention). OpenVDB's Mat4 uses row vectors (p' = p * M, translation in
// row 3), hence the transposition.
void fill_transform(const openvdb::math::Transform& xf, GridInfo& info) {
    info.linear = xf.isLinear();
    info.map_type = xf.mapType();
    const auto vs = xf.voxelSize();
    info.voxel_size = {vs[0], vs[1], vs[2]};
    if (!info.linear) {
        for (auto& v : info.world_from_index) v = 0.0;
        return;
    }
    const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) info.world_from_index[r * 4 + c] = m(c, r);
        info.world_from_index[r * 4 + 3] = m(3, r);
    }
}

std::string value_type_of(const openvdb::GridBase& g) { return g.valueType(); }

GridInfo make_info(const openvdb::GridBase& g, bool topology_loaded) {
    GridInfo info;
    info.name = g.getName();
    info.value_type = value_type_of(g);
    info.grid_class = openvdb::GridBase::gridClassToString(g.getGridClass());
    fill_transform(g.constTransform(), info);
    info.metadata = collect_meta(g);
    // Voxel count and bounding box: from the loaded tree when there is one,
    // otherwise from the statistics OpenVDB writes into the grid metadata.
    info.active_voxels = 0;
    info.bbox_min = {0, 0, 0};
    info.bbox_max = {-1, -1, -1};
    info.empty = true;
    if (topology_loaded) {
        info.active_voxels = g.activeVoxelCount();
        const openvdb::CoordBBox bb = g.evalActiveVoxelBoundingBox();
        if (!bb.empty()) {
            info.empty = false;
            info.bbox_min = {bb.min().x(), bb.min().y(), bb.min().z()};
            info.bbox_max = {bb.max().x(), bb.max().y(), bb.max().z()};
        }
    } else {
        auto cnt = g.getMetadata<openvdb::Int64Metadata>(openvdb::GridBase::META_FILE_VOXEL_COUNT);
        auto bmin = g.getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MIN);
        auto bmax = g.getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MAX);
        if (cnt) info.active_voxels = static_cast<uint64_t>(cnt->value());
        if (bmin && bmax && info.active_voxels > 0) {
            info.empty = false;
            info.bbox_min = {bmin->value()[0], bmin->value()[1], bmin->value()[2]};
            info.bbox_max = {bmax->value()[0], bmax->value()[1], bmax->value()[2]};
        }
    }
    return info;
}

// A grid's info from its metadata and transform alone (any value type).
GridInfo head_info(const openvdb::MetaMap& meta, const openvdb::math::Transform& xf) {
    GridInfo info;
    info.grid_class = "unknown";
    if (auto c = meta.getMetadata<openvdb::StringMetadata>(openvdb::GridBase::META_GRID_CLASS))
        info.grid_class = openvdb::GridBase::gridClassToString(openvdb::GridBase::stringToGridClass(c->value()));
    fill_transform(xf, info);
    info.metadata = collect_meta(meta);
    info.active_voxels = 0;
    info.bbox_min = {0, 0, 0};
    info.bbox_max = {-1, -1, -1};
    info.empty = true;
    auto cnt = meta.getMetadata<openvdb::Int64Metadata>(openvdb::GridBase::META_FILE_VOXEL_COUNT);
    auto bmin = meta.getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MIN);
    auto bmax = meta.getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MAX);
    if (cnt) info.active_voxels = static_cast<uint64_t>(cnt->value());
    if (bmin && bmax && info.active_voxels > 0) {
        info.empty = false;
        info.bbox_min = {bmin->value()[0], bmin->value()[1], bmin->value()[2]};
        info.bbox_max = {bmax->value()[0], bmax->value()[1], bmax->value()[2]};
    }
    return info;
}

template <typename V> struct Channels;
template <> struct Channels<float> {
    static constexpr uint32_t N = 1;
    static void put(float* dst, float v) { dst[0] = v; }
    static float get(const float* src) { return src[0]; }
};
template <> struct Channels<double> {
    static constexpr uint32_t N = 1;
    static void put(float* dst, double v) { dst[0] = static_cast<float>(v); }
};
template <> struct Channels<openvdb::Vec3s> {
    static constexpr uint32_t N = 3;
    static void put(float* dst, const openvdb::Vec3s& v) {
        dst[0] = v[0];
        dst[1] = v[1];
        dst[2] = v[2];
    }
    static openvdb::Vec3s get(const float* src) { return openvdb::Vec3s(src[0], src[1], src[2]); }
};

// Tiles at every internal level that are active or differ from the
// background (inactive tiles still take part in trilinear interpolation),
// and the background. Leaves are copied separately, in bulk.
template <typename GridT> void layout_of(const GridT& grid, GridLayout& out) {
    using ValueT = typename GridT::ValueType;
    using Ch = Channels<ValueT>;
    constexpr uint32_t N = Ch::N;
    const auto& tree = grid.tree();
    const ValueT bg = tree.background();
    out.channels = N;
    out.leaf_count = tree.leafCount();
    float tmp[3];
    Ch::put(tmp, bg);
    for (uint32_t i = 0; i < N; ++i) out.background.push_back(tmp[i]);
    auto tile = [&](const Coord& c, uint8_t level, bool active, const ValueT& v) {
        TileRecord r{};
        r.origin = {c.x(), c.y(), c.z()};
        r.level = level;
        r.active = active;
        Ch::put(r.value.data(), v);
        out.tiles.push_back(r);
    };
    // An internal node's tiles straight from its table and masks: the
    // value iterators took about 15 ns an entry, 1-2 ms of a load, for the
    // 4096 or 32768 entries of every node.
    auto node_tiles = [&](const auto& node, uint8_t level) {
        using NodeT = std::decay_t<decltype(node)>;
        const auto* table = node.getTable();
        const auto& children = node.getChildMask();
        const auto& active = node.getValueMask();
        for (openvdb::Index n = 0; n < NodeT::NUM_VALUES; ++n) {
            if (children.isOn(n)) continue;
            const ValueT& v = table[n].getValue();
            const bool on = active.isOn(n);
            if (on || v != bg) tile(node.offsetToGlobalCoord(n), level, on, v);
        }
    };
    const auto& root = tree.root();
    for (auto it = root.cbeginValueAll(); it; ++it)
        if (it.isValueOn() || *it != bg) tile(it.getCoord(), 3, it.isValueOn(), *it);
    for (auto c2 = root.cbeginChildOn(); c2; ++c2) {
        node_tiles(*c2, 2);
        for (auto c1 = c2->cbeginChildOn(); c1; ++c1) node_tiles(*c1, 1);
    }
}

template <typename GridT>
void copy_leaves_of(const GridT& grid, rust::Slice<int32_t> origins, rust::Slice<float> values,
                    rust::Slice<uint64_t> masks) {
    using ValueT = typename GridT::ValueType;
    constexpr size_t N = Channels<ValueT>::N;
    const size_t n = grid.tree().leafCount();
    if (origins.size() != 3 * n || values.size() != 512 * N * n || masks.size() != 8 * n)
        throw std::runtime_error("leaf buffers have the wrong size");
    using LeafT = typename GridT::TreeType::LeafNodeType;
    std::vector<const LeafT*> leaves;
    leaves.reserve(n);
    for (auto leaf = grid.tree().cbeginLeaf(); leaf; ++leaf) leaves.push_back(leaf.getLeaf());
    if (leaves.size() != n) throw std::runtime_error("the leaf count changed while copying");
    for (const LeafT* leaf : leaves)
        if (leaf->buffer().data() == nullptr) throw std::runtime_error("a leaf's data could not be loaded");
    // Two threads or more halve the cost of the first touch of Rust's fresh
    // pages, which dominates this copy.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t l = r.begin(); l != r.end(); ++l) {
            const LeafT* leaf = leaves[l];
            const Coord o = leaf->origin();
            origins[3 * l] = o.x();
            origins[3 * l + 1] = o.y();
            origins[3 * l + 2] = o.z();
            const auto& mask = leaf->getValueMask();
            for (openvdb::Index w = 0; w < 8; ++w) masks[8 * l + w] = mask.template getWord<Index64>(w);
            const ValueT* data = leaf->buffer().data();
            float* dst = values.data() + 512 * N * l;
            if constexpr (std::is_same<ValueT, double>::value) {
                for (int i = 0; i < 512; ++i) dst[i] = static_cast<float>(data[i]);
            } else {
                std::memcpy(dst, data, 512 * N * sizeof(float));
            }
        }
    });
}

openvdb::GridBase::Ptr read_one(OpenFile& f, const std::string& grid) {
    if (!f.file.hasGrid(grid)) throw std::runtime_error("no grid named '" + grid + "'");
    return f.file.readGrid(grid);
}

template <typename GridT> typename GridT::Ptr build_grid(const GridData& d) {
    using ValueT = typename GridT::ValueType;
    using Ch = Channels<ValueT>;
    constexpr uint32_t N = Ch::N;
    if (d.channels != N) throw std::runtime_error("channel count does not match the value type");
    if (d.background.size() != N) throw std::runtime_error("background has the wrong number of channels");
    const size_t leaves = d.leaf_origins.size() / 3;
    if (d.leaf_values.size() != leaves * 512 * N || d.leaf_masks.size() != leaves * 8)
        throw std::runtime_error("leaf arrays have inconsistent lengths");
    const size_t tiles = d.tile_levels.size();
    if (d.tile_origins.size() != tiles * 3 || d.tile_active.size() != tiles || d.tile_values.size() != tiles * N)
        throw std::runtime_error("tile arrays have inconsistent lengths");

    auto grid = GridT::create(Ch::get(d.background.data()));
    grid->setName(std::string(d.info.name));
    grid->setGridClass(openvdb::GridBase::stringToGridClass(std::string(d.info.grid_class)));
    openvdb::Mat4d m = openvdb::Mat4d::identity();
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) m(c, r) = d.info.world_from_index[r * 4 + c];
        m(3, r) = d.info.world_from_index[r * 4 + 3];
    }
    grid->setTransform(openvdb::math::Transform::createLinearTransform(m));
    auto& tree = grid->tree();
    for (size_t t = 0; t < tiles; ++t) {
        const Coord c(d.tile_origins[3 * t], d.tile_origins[3 * t + 1], d.tile_origins[3 * t + 2]);
        tree.addTile(d.tile_levels[t], c, Ch::get(&d.tile_values[N * t]), d.tile_active[t]);
    }
    for (size_t l = 0; l < leaves; ++l) {
        const Coord o(d.leaf_origins[3 * l], d.leaf_origins[3 * l + 1], d.leaf_origins[3 * l + 2]);
        auto* leaf = tree.touchLeaf(o);
        ValueT* data = leaf->buffer().data();
        std::memcpy(static_cast<void*>(data), &d.leaf_values[l * 512 * N], 512 * N * sizeof(float));
        typename GridT::TreeType::LeafNodeType::NodeMaskType mask;
        for (openvdb::Index w = 0; w < 8; ++w) mask.template getWord<Index64>(w) = d.leaf_masks[l * 8 + w];
        leaf->setValueMask(mask);
    }
    return grid;
}

template <typename GridT>
void sample_into(const openvdb::GridBase& base, rust::Slice<const double> xyz, rust::Vec<float>& out) {
    const auto& grid = static_cast<const GridT&>(base);
    openvdb::tools::GridSampler<GridT, openvdb::tools::BoxSampler> sampler(grid);
    using Ch = Channels<typename GridT::ValueType>;
    float tmp[3];
    for (size_t i = 0; i + 2 < xyz.size(); i += 3) {
        Ch::put(tmp, sampler.wsSample(openvdb::Vec3d(xyz[i], xyz[i + 1], xyz[i + 2])));
        for (uint32_t c = 0; c < Ch::N; ++c) out.push_back(tmp[c]);
    }
}

} // namespace

rust::String openvdb_version() { return rust::String(openvdb::getLibraryAbiVersionString()); }

struct LoadedGrid::Impl {
    openvdb::GridBase::Ptr grid;
    GridInfo info;
};

LoadedGrid::LoadedGrid() : impl(new Impl) {}
LoadedGrid::~LoadedGrid() = default;

rust::Vec<MetaEntry> read_metadata(rust::Slice<const uint8_t> bytes, const StreamVersion& v) {
    TaggedStream s(bytes, v);
    openvdb::MetaMap meta;
    meta.readMeta(s.is);
    s.expect_consumed(bytes.size(), "the file metadata");
    return collect_meta(meta);
}

GridInfo read_grid_head(rust::Slice<const uint8_t> bytes, const StreamVersion& v) {
    TaggedStream s(bytes, v);
    uint32_t compression = 0;
    s.is.read(reinterpret_cast<char*>(&compression), sizeof compression);
    openvdb::MetaMap meta;
    meta.readMeta(s.is);
    openvdb::math::Transform xf;
    xf.read(s.is);
    s.expect_consumed(bytes.size(), "the grid's metadata and transform");
    return head_info(meta, xf);
}

std::unique_ptr<LoadedGrid> load_grid_bytes(rust::Slice<const uint8_t> bytes, rust::Str unique_name,
                                            rust::Str type_name, bool half, const StreamVersion& v) {
    TaggedStream s(bytes, v);
    const std::string type = to_std(type_name);
    if (!openvdb::GridBase::isRegistered(type)) throw std::runtime_error("grid type " + type + " is not registered");
    auto grid = openvdb::GridBase::createGrid(type);
    grid->setSaveFloatAsHalf(half);
    const openvdb::io::GridDescriptor gd(to_std(unique_name), type, half);
    ArchiveReader::read(grid, gd, s.is);
    s.expect_consumed(bytes.size(), "the grid");
    auto out = std::make_unique<LoadedGrid>();
    out->impl->grid = grid;
    out->impl->info = make_info(*grid, false);
    return out;
}


// Dispatches on the value types we read; returns false for any other.
template <typename F> bool with_typed(const openvdb::GridBase& g, F&& f) {
    if (g.isType<openvdb::FloatGrid>()) return f(static_cast<const openvdb::FloatGrid&>(g)), true;
    if (g.isType<openvdb::DoubleGrid>()) return f(static_cast<const openvdb::DoubleGrid&>(g)), true;
    if (g.isType<openvdb::Vec3SGrid>()) return f(static_cast<const openvdb::Vec3SGrid&>(g)), true;
    return false;
}

GridLayout grid_layout(const LoadedGrid& g) {
    GridLayout out;
    out.info = g.impl->info;
    out.channels = 0; // unsupported value type or transform: the caller reports it
    out.leaf_count = 0;
    if (!out.info.linear) return out;
    with_typed(*g.impl->grid, [&](const auto& typed) { layout_of(typed, out); });
    return out;
}

// `values` is memory Rust has not initialised: every float of it is
// written before this returns normally (copy_leaves_of checks the sizes and
// the leaves before it writes anything, then copies every leaf whole).
void copy_leaves(const LoadedGrid& g, rust::Slice<int32_t> origins, float* values, size_t values_len,
                 rust::Slice<uint64_t> masks) {
    const rust::Slice<float> v(values, values_len);
    if (!with_typed(*g.impl->grid, [&](const auto& typed) { copy_leaves_of(typed, origins, v, masks); }))
        throw std::runtime_error("unsupported value type " + g.impl->grid->valueType());
}

void write_grids(rust::Str path, rust::Slice<const GridData> grids, rust::Str creator) {
    ensure_initialized();
    openvdb::GridPtrVec out;
    for (const auto& d : grids) {
        if (d.channels == 1) {
            out.push_back(build_grid<openvdb::FloatGrid>(d));
        } else if (d.channels == 3) {
            out.push_back(build_grid<openvdb::Vec3SGrid>(d));
        } else {
            throw std::runtime_error("grid '" + std::string(d.info.name) + "' has an unsupported channel count");
        }
    }
    openvdb::MetaMap meta;
    meta.insertMeta("creator", openvdb::StringMetadata(to_std(creator)));
    openvdb::io::File file(to_std(path));
    file.write(out, meta);
    file.close();
}

rust::Vec<float> box_sample_world(rust::Str path, rust::Str grid, rust::Slice<const double> xyz) {
    OpenFile f(to_std(path));
    auto base = read_one(f, to_std(grid));
    rust::Vec<float> out;
    out.reserve(xyz.size());
    if (base->isType<openvdb::FloatGrid>()) {
        sample_into<openvdb::FloatGrid>(*base, xyz, out);
    } else if (base->isType<openvdb::Vec3SGrid>()) {
        sample_into<openvdb::Vec3SGrid>(*base, xyz, out);
    } else if (base->isType<openvdb::DoubleGrid>()) {
        const auto& g = static_cast<const openvdb::DoubleGrid&>(*base);
        openvdb::tools::GridSampler<openvdb::DoubleGrid, openvdb::tools::BoxSampler> s(g);
        for (size_t i = 0; i + 2 < xyz.size(); i += 3)
            out.push_back(static_cast<float>(s.wsSample(openvdb::Vec3d(xyz[i], xyz[i + 1], xyz[i + 2]))));
    } else {
        throw std::runtime_error("grid type " + base->valueType() + " cannot be sampled");
    }
    return out;
}

ReadStats openvdb_read_stats(rust::Str path, rust::Str grid) {
    ensure_initialized();
    const auto t0 = std::chrono::steady_clock::now();
    OpenFile f(to_std(path));
    auto base = read_one(f, to_std(grid));
    const auto t1 = std::chrono::steady_clock::now();
    ReadStats s;
    s.seconds = std::chrono::duration<double>(t1 - t0).count();
    s.mem_bytes = base->memUsage();
    s.active_voxels = base->activeVoxelCount();
    return s;
}

// Files that the writer refuses to make on purpose, so that the tests can
// check how the reader reports them: an int32 grid and a frustum transform.
void write_test_fixture(rust::Str path, rust::Str kind) {
    ensure_initialized();
    openvdb::GridPtrVec grids;
    const std::string k = to_std(kind);
    if (k == "int32") {
        auto g = openvdb::Int32Grid::create(0);
        g->setName("labels");
        g->tree().setValue(Coord(1, 2, 3), 7);
        grids.push_back(g);
    } else if (k == "double") {
        // A double grid: vdbphoton reads it as f32. Voxels, an inactive
        // value, and an 8^3 tile.
        auto g = openvdb::DoubleGrid::create(0.0);
        g->setName("density");
        g->setTransform(openvdb::math::Transform::createLinearTransform(0.25));
        for (int i = 0; i < 20; ++i)
            g->tree().setValue(Coord(i, 2 * i - 10, 3), 0.1 + 0.037 * i + 1e-12 * i);
        g->tree().setValueOff(Coord(5, 5, 5), 0.75);
        g->tree().addTile(1, Coord(64, 0, 0), 2.5, true);
        grids.push_back(g);
    } else if (k == "frustum") {
        auto g = openvdb::FloatGrid::create(0.0f);
        g->setName("density");
        g->tree().setValue(Coord(1, 2, 3), 0.5f);
        const openvdb::BBoxd box(openvdb::Vec3d(0, 0, 0), openvdb::Vec3d(16, 16, 16));
        g->setTransform(openvdb::math::Transform::createFrustumTransform(box, 0.5, 2.0, 0.1));
        grids.push_back(g);
    } else if (k == "half" || k == "zip" || k == "uncompressed" || k == "inactive" || k == "instance") {
        // Storage variants of one small float grid, for the reader's walk
        // and the fuzzer's seeds: half floats, zlib, no compression at all,
        // leaves whose inactive values need each mask-compression case, and
        // a second grid sharing the first one's tree.
        auto g = openvdb::FloatGrid::create(0.0f);
        g->setName("density");
        g->setGridClass(openvdb::GRID_FOG_VOLUME);
        for (int i = 0; i < 40; ++i) g->tree().setValue(Coord(i, (7 * i) % 23, (3 * i) % 17), 0.05f + 0.02f * i);
        g->tree().addTile(1, Coord(64, 0, 0), 0.5f, true);
        g->tree().addTile(2, Coord(256, 0, 0), 0.25f, true);
        if (k == "inactive") {
            // One other inactive value (metadata 2), background plus one
            // (4), two non-background values (5), more than two (6).
            g->tree().setValueOff(Coord(1, 1, 1), 0.75f);
            g->tree().setValueOn(Coord(17, 1, 1), 0.5f);
            g->tree().setValueOff(Coord(18, 1, 1), 0.125f);
            g->tree().setValueOn(Coord(33, 1, 1), 0.5f);
            for (int z = 0; z < 8; ++z) g->tree().setValueOff(Coord(33, 2, z), z % 2 ? 0.3f : 0.6f);
            g->tree().setValueOn(Coord(49, 1, 1), 0.5f);
            for (int z = 0; z < 8; ++z) g->tree().setValueOff(Coord(49, 2, z), 0.1f * z);
        }
        if (k == "half") g->setSaveFloatAsHalf(true);
        grids.push_back(g);
        if (k == "instance") {
            auto inst = g->copyGrid(); // shares the tree: written as an instance
            inst->setName("density_copy");
            inst->setTransform(openvdb::math::Transform::createLinearTransform(0.5));
            grids.push_back(inst);
        }
        openvdb::io::File file(to_std(path));
        if (k == "zip") file.setCompression(openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
        if (k == "uncompressed") file.setCompression(openvdb::io::COMPRESS_NONE);
        file.write(grids);
        file.close();
        return;
    } else {
        throw std::runtime_error("unknown fixture kind '" + k + "'");
    }
    openvdb::io::File file(to_std(path));
    file.write(grids);
    file.close();
}

} // namespace ffi
} // namespace vdbphoton
