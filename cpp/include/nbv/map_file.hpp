// The checks OctoMap's file readers leave out: a truncated, padded or corrupted .ot / .bt file
// loaded as a smaller or garbled map (and a named pipe blocked the reader forever).
#pragma once

#include <cstdint>
#include <string>

namespace nbv {

/// What an OctoMap file's header says: its tree type, node count and resolution (metres).
struct MapFileHeader {
  std::string id;
  std::uint64_t size = 0;
  double res = 0;
};

/// Reads the header of an OctoMap file (`binary`: .bt, else .ot) and walks its node stream
/// without building the tree. Throws std::invalid_argument naming the file if it is not a regular
/// file, its header is malformed, its stream ends before the last node or goes on after it, its
/// node count is not the header's, a node lies below OctoMap's 16 levels or (.ot) a log-odds value
/// is not finite.
MapFileHeader check_map_file(const std::string& path, bool binary);

}  // namespace nbv
