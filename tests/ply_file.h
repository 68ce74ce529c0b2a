/* SPDX-License-Identifier: BSD-3-Clause */
// The PLY files of the programs' --initial-ply and --final-ply (lib/formats/ply.h), read
// back by the tests: the vertex count the header announces, and each vertex's position and color.
#ifndef SBA_TESTS_PLY_FILE_H
#define SBA_TESTS_PLY_FILE_H

#include <array>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace plytest {

struct Vertex {
  std::array<double, 3> x{};
  std::array<int, 3> rgb{};
  std::array<std::string, 3> text;  // the coordinates as written
};

struct PlyFile {
  long announced = -1;  // "element vertex N"; -1: no such line
  std::vector<Vertex> vertices;
  bool header_ok = false;  // ascii PLY with x y z and red green blue, in that order
};

inline PlyFile read_ply(const std::string &path) {
  std::ifstream in(path);
  PlyFile f;
  std::string line, header;
  while (std::getline(in, line) && line != "end_header") {
    header += line + "\n";
    if (line.rfind("element vertex ", 0) == 0) f.announced = std::stol(line.substr(15));
  }
  f.header_ok = header.rfind("ply\nformat ascii 1.0\n", 0) == 0 &&
                header.find("property double x\nproperty double y\nproperty double z\nproperty uchar red\n"
                            "property uchar green\nproperty uchar blue\n") != std::string::npos;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    Vertex v;
    for (int k = 0; k < 3; ++k) {
      words >> v.text[k];
      v.x[k] = std::stod(v.text[k]);
    }
    for (int &c : v.rgb) words >> c;
    f.vertices.push_back(v);
  }
  return f;
}

}  // namespace plytest

#endif  // SBA_TESTS_PLY_FILE_H
