#include "nbv/map_file.hpp"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace nbv {

namespace {

constexpr int kTreeDepth = 16;  // OctoMap's levels below the root

[[noreturn]] void refuse(const std::string& path, const std::string& why) {
  throw std::invalid_argument("map file '" + path + "' " + why);
}

MapFileHeader read_header(std::istream& in, const std::string& path, bool binary) {
  const std::string first = binary ? "# Octomap OcTree binary file" : "# Octomap OcTree file";
  std::string line;
  if (!std::getline(in, line) || line.rfind(first, 0) != 0)
    refuse(path,
           std::string("is not a readable OctoMap ") + (binary ? ".bt" : ".ot") +
               " file (its first line is not '" + first + "'" +
               (binary ? "; a .bt of OctoMap 1.0 has none: convert it with convert_octree)" : ")"));
  MapFileHeader h;
  bool size = false, res = false;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string key;
    words >> key;
    if (key.empty() || key[0] == '#') continue;
    if (key == "data") {
      if (!size || !res) refuse(path, "has no 'size' or 'res' line before its data");
      return h;
    }
    if (key == "id") words >> h.id;
    if (key == "size" && !(size = bool(words >> h.size)))
      refuse(path, "has an unreadable 'size' line: " + line.substr(0, 80));
    if (key == "res" && !(res = bool(words >> h.res)))
      refuse(path, "has an unreadable 'res' line: " + line.substr(0, 80));
  }
  refuse(path, "ends in its header (no 'data' line)");
}

// Walks the node stream as OcTree::readData (.ot: a float log-odds and a child mask a node) or
// readBinaryData (.bt: two bytes of 2-bit child codes a node; 11 = an inner child) do, counting
// nodes and checking what they leave unchecked.
class NodeWalk {
 public:
  NodeWalk(std::streambuf& in, const std::string& path, std::uint64_t expected, bool binary)
      : in_(in), path_(path), expected_(expected), binary_(binary) {}

  void run() {
    if (expected_ > 0) node(0);  // (OctoMap writes an empty tree as its header alone)
    if (count_ != expected_)
      refuse(path_, "holds " + std::to_string(count_) + " nodes where its header counts " +
                        std::to_string(expected_) + ": a damaged file");
    if (in_.sgetc() != std::char_traits<char>::eof())
      refuse(path_,
             "goes on after its last node (" + std::to_string(count_) + " nodes): a damaged file");
  }

 private:
  void read(char* out, std::streamsize n) {
    if (in_.sgetn(out, n) != n)
      refuse(path_, "ends in node " + std::to_string(count_) + " of the " +
                        std::to_string(expected_) + " its header counts: a truncated file");
  }

  void node(int depth) {
    if (++count_ > expected_)
      refuse(path_, "holds more nodes than the " + std::to_string(expected_) +
                        " its header counts: a damaged file");
    char bytes[5];
    bool inner[8] = {};
    if (binary_) {
      read(bytes, 2);
      for (int i = 0; i < 8; ++i) {
        const int code = (static_cast<unsigned char>(bytes[i / 4]) >> (2 * (i % 4))) & 3;
        if (code == 0) continue;
        child(depth);
        if (code == 3)
          inner[i] = true;
        else
          ++count_;  // a leaf: no bytes of its own
      }
      // an inner node without children: OctoMap gives it a log-odds of -FLT_MAX
      if (depth > 0 && bytes[0] == 0 && bytes[1] == 0)
        refuse(path_, "has an inner node without children (node " + std::to_string(count_) +
                          "): a damaged file");
    } else {
      read(bytes, 5);
      float value;
      std::memcpy(&value, bytes, sizeof value);
      if (!std::isfinite(value))
        refuse(path_, "holds a log-odds value of " + std::to_string(value) + " (node " +
                          std::to_string(count_) + "): a damaged file");
      for (int i = 0; i < 8; ++i)
        if ((static_cast<unsigned char>(bytes[4]) >> i) & 1) {
          child(depth);
          inner[i] = true;
        }
    }
    for (bool in : inner)
      if (in) node(depth + 1);
  }

  void child(int depth) const {
    if (depth >= kTreeDepth)
      refuse(path_, "has a node below OctoMap's " + std::to_string(kTreeDepth) +
                        " levels: a damaged file");
  }

  std::streambuf& in_;
  const std::string& path_;
  std::uint64_t expected_, count_ = 0;
  bool binary_;
};

}  // namespace

MapFileHeader check_map_file(const std::string& path, bool binary) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) refuse(path, "is a directory");
  if (!std::filesystem::is_regular_file(path, ec))  // (a named pipe blocked OctoMap's reader)
    refuse(path, "is not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) refuse(path, "cannot be opened: " + std::string(std::strerror(errno)));
  MapFileHeader h = read_header(in, path, binary);
  if (h.id.empty()) h.id = "OcTree";  // (as OctoMap reads a header without one)
  if (h.id != "OcTree")               // another tree's nodes hold more than a log-odds
    refuse(path, "holds a " + h.id.substr(0, 40) + ", not an OcTree");
  NodeWalk(*in.rdbuf(), path, h.size, binary).run();
  return h;
}

}  // namespace nbv
