// The C++ half of the vdbphoton <-> OpenVDB bridge.
//
// This directory is the only place in the project that includes OpenVDB
// headers. Everything crosses the boundary in bulk: whole 8^3 leaves (origin,
// 512 values, active mask) and every tile, in flat arrays, with the transform
// once per grid. Every function may throw; each is declared `-> Result` on the
// Rust side, so an exception becomes an `Err` instead of terminating.
#pragma once
#include "rust/cxx.h"
#include <cstdint>
#include <memory>

namespace vdbphoton {
namespace ffi {

struct MetaEntry;
struct GridInfo;
struct FileInfo;
struct GridData;
struct ReadStats;
struct GridLayout;
struct StreamVersion;

/// A grid read by OpenVDB, held on the C++ side until Rust has copied it.
/// Its contents are defined in vdb_bridge.cc, so this header stays free of
/// OpenVDB includes.
class LoadedGrid {
public:
    struct Impl;
    LoadedGrid();
    ~LoadedGrid();
    std::unique_ptr<Impl> impl;
};

rust::Vec<MetaEntry> read_metadata(rust::Slice<const uint8_t> bytes, const StreamVersion& v);
GridInfo read_grid_head(rust::Slice<const uint8_t> bytes, const StreamVersion& v);
std::unique_ptr<LoadedGrid> load_grid_bytes(rust::Slice<const uint8_t> bytes, rust::Str unique_name,
                                            rust::Str type_name, bool half, const StreamVersion& v);
GridLayout grid_layout(const LoadedGrid& g);
void copy_leaves(const LoadedGrid& g, rust::Slice<int32_t> origins, float* values, size_t values_len,
                 rust::Slice<uint64_t> masks);
void write_grids(rust::Str path, rust::Slice<const GridData> grids, rust::Str creator);
rust::Vec<float> box_sample_world(rust::Str path, rust::Str grid, rust::Slice<const double> xyz);
ReadStats openvdb_read_stats(rust::Str path, rust::Str grid);
void write_test_fixture(rust::Str path, rust::Str kind);
rust::String openvdb_version();

} // namespace ffi
} // namespace vdbphoton
