// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: the image lists of sbarefine's --hold-poses (colmap::parse_image_list) and
// --hold-poses-file (colmap::parse_image_names), each input taken as both, against a fixed model
// whose names are the hard cases: digits that are another image's IMAGE_ID, a leading zero, a
// sign, a comma, a blank, "all", a name two images share, digits past 32 bits. What is
// accepted must hold exactly the images its items name by the rule of colmap_sba.h, found
// here by a plain scan of the images; what is refused must have an item that names none (or
// an empty one), and say which in one line.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "formats/colmap_sba.h"
#include "fuzz_common.h"

namespace colmap = sbaformats::colmap;

namespace {

using sbafuzz::require;

// The images alone (IMAGE_ID, q, t, CAMERA_ID, NAME, keypoints): all that a list is resolved
// against. Made once, never changed.
const colmap::Model &model() {
  static const colmap::Model m{
      {},
      {{10, {1, 0, 0, 0}, {}, 1, "img_0.png", {}},
       {13, {1, 0, 0, 0}, {}, 1, "10", {}},
       {0, {1, 0, 0, 0}, {}, 1, "zero.png", {}},
       {4294967295u, {1, 0, 0, 0}, {}, 1, "last.png", {}},
       {16, {1, 0, 0, 0}, {}, 1, "010", {}},
       {19, {1, 0, 0, 0}, {}, 1, "+7", {}},
       {22, {1, 0, 0, 0}, {}, 1, "a,b.png", {}},
       {25, {1, 0, 0, 0}, {}, 1, "x y.png", {}},
       {28, {1, 0, 0, 0}, {}, 1, "dup.png", {}},
       {31, {1, 0, 0, 0}, {}, 1, "dup.png", {}},
       {34, {1, 0, 0, 0}, {}, 1, "all", {}},
       {37, {1, 0, 0, 0}, {}, 1, "12", {}},
       {40, {1, 0, 0, 0}, {}, 1, "4294967296", {}},
       {43, {1, 0, 0, 0}, {}, 1, "\xc3\xa9t\xc3\xa9.jpg", {}}},
      {}};
  return m;
}

// The images an item names, read off the rule literally: with ids, the image whose IMAGE_ID
// written in decimal is the item, if any; else every image whose NAME is the item.
std::vector<std::size_t> named(const std::string &item, bool ids) {
  const std::vector<colmap::Image> &images = model().images;
  std::vector<std::size_t> out;
  for (std::size_t j = 0; ids && j < images.size(); ++j)
    if (std::to_string(images[j].id) == item) return {j};
  for (std::size_t j = 0; j < images.size(); ++j)
    if (images[j].name == item) out.push_back(j);
  return out;
}

// Whether item is written as the rule writes an IMAGE_ID: it decides the form of a refusal.
bool plain_decimal(const std::string &item) {
  return !item.empty() && item.find_first_not_of("0123456789") == std::string::npos &&
         (item.size() == 1 || item[0] != '0');
}

// A refusal of an item that names no image: one line that quotes the item as given (a
// control character in it aside, which must not reach the message as itself).
void check_no_image(const std::string &why, const std::string &prefix, const std::string &item, bool ids) {
  const std::string start =
      prefix + "no image has the " + (ids && plain_decimal(item) ? "IMAGE_ID or NAME '" : "NAME '");
  require(why.compare(0, start.size(), start) == 0 && why.size() > start.size() && why.back() == '\'',
          "the refusal of '" + item + "' is not \"" + start + "...'\": " + why);
  bool printable = true;
  for (const char c : why) printable = printable && static_cast<unsigned char>(c) >= 0x20 && c != 0x7f;
  require(printable, "a control character in the message: " + why);
  bool plain = true;
  for (const char c : item) plain = plain && static_cast<unsigned char>(c) >= 0x20 && c != 0x7f;
  if (plain) require(why == start + item + "'", "the message does not quote the item as given: " + why);
}

// held as the parser left it against what the items name; why the parser's refusal.
void check_outcome(const std::string &why, const std::vector<char> &held, const std::vector<char> &expected,
                   bool refused) {
  if (refused) {
    require(!why.empty(), "a list with an item that names no image was accepted");
    require(held.empty(), "a refused list changed the flags");
    return;
  }
  require(why.empty(), "a list whose every item names an image was refused: " + why);
  require(held == expected, "the images held are not the ones the items name");
}

void check_list(const std::string &list) {
  std::vector<char> held;
  const std::string why = colmap::parse_image_list(model(), list, &held);
  std::vector<char> expected(model().images.size(), list == "all" ? 1 : 0);
  std::vector<std::string> items;
  for (std::size_t pos = 0; list != "all";) {
    std::size_t end = list.find(',', pos);
    if (end == std::string::npos) end = list.size();
    items.push_back(list.substr(pos, end - pos));
    if (end == list.size()) break;
    pos = end + 1;
  }
  // The list is read whole before its items are looked up: an empty item is refused first.
  for (std::size_t k = 0; k < items.size(); ++k)
    if (items[k].empty()) {
      const std::string number = std::to_string(k + 1);
      require(why == "item " + number + " is empty (two commas in a row, or a comma at an end)",
              "the refusal does not name the empty item " + number + ": " + why);
      return check_outcome(why, held, expected, true);
    }
  for (const std::string &item : items) {
    const std::vector<std::size_t> js = named(item, true);
    if (js.empty()) {
      check_no_image(why, "", item, true);
      return check_outcome(why, held, expected, true);
    }
    for (std::size_t j : js) expected[j] = 1;
  }
  check_outcome(why, held, expected, false);
}

void check_file(const std::string &text) {
  const std::string name = "fuzz-input";
  std::vector<char> held;
  const std::string why = colmap::parse_image_names(model(), text, name, &held);
  std::vector<char> expected(model().images.size(), 0);
  bool refused = false;
  for (std::size_t pos = 0, line = 1; pos < text.size() && !refused; ++line) {
    std::size_t end = text.find('\n', pos);
    const bool broken = end != std::string::npos;
    if (!broken) end = text.size();
    std::string item = text.substr(pos, end - pos);
    if (broken && !item.empty() && item.back() == '\r') item.pop_back();
    pos = end + 1;
    if (item.empty()) continue;
    const std::vector<std::size_t> js = named(item, false);
    for (std::size_t j : js) expected[j] = 1;
    refused = js.empty();
    if (refused) check_no_image(why, name + ":" + std::to_string(line) + ": ", item, false);
  }
  check_outcome(why, held, expected, refused);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
  const std::string text(reinterpret_cast<const char *>(data), size);
  check_list(text);
  check_file(text);
  return 0;
}
