// SPDX-License-Identifier: BSD-3-Clause
#include "cli/ply_options.h"

#include <cstdio>

namespace sbacli {

void add_ply_options(std::vector<Option> *table, std::string *initial, std::string *final_ply, bool colored) {
  table->push_back({"initial-ply", "FILE",
                    std::string("write the initial points ") + (colored ? "(with their colors) " : "(grey) ") +
                        "and camera centres (red) as PLY",
                    [initial](const std::string &v) { return to_file(v, initial); }});
  table->push_back({"final-ply", "FILE", "the same for the refined model",
                    [final_ply](const std::string &v) { return to_file(v, final_ply); }});
}

bool write_ply_option(const std::string &path, const sbaformats::Cloud &cloud,
                      sbaformats::OutputSet *outputs) {
  std::string why;
  if (path.empty() || sbaformats::write_ply(path, cloud, &why, outputs)) return true;
  std::fprintf(stderr, "%s: %s\n", path.c_str(), why.c_str());
  return false;
}

}  // namespace sbacli
