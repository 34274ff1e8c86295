// docs/scenes.md documents every world setting's default in a table; this test reads the table
// and checks it against the engine: each WorldSettings field of scene.proto has a row, each row
// names a field, and each default equals fulcrum::WorldSettings{} as the scene conversion
// writes it (world_settings_to_proto), exactly.
#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "scene_convert.h"

namespace fulcrum {
namespace {

namespace pb = google::protobuf;

// Rows of the table under "## World settings": field name (first cell, in backticks) to the
// default (second cell).
std::map<std::string, std::string> documented_defaults() {
  std::ifstream in(std::string(FULCRUM_DOCS_DIR) + "/scenes.md");
  EXPECT_TRUE(in) << "docs/scenes.md";
  std::map<std::string, std::string> rows;
  bool in_section = false;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("## ", 0) == 0) in_section = line.rfind("## World settings", 0) == 0;
    if (!in_section || line.rfind("| `", 0) != 0) continue;
    const size_t name_end = line.find('`', 3);
    const size_t cell = line.find('|', name_end);
    const size_t cell_end = line.find('|', cell + 1);
    std::string value = line.substr(cell + 1, cell_end - cell - 1);
    value = value.substr(value.find_first_not_of(' '));
    value = value.substr(0, value.find_last_not_of(' ') + 1);
    rows[line.substr(3, name_end - 3)] = value;
  }
  return rows;
}

// A documented number: "0.035", "-10" or a fraction "1/60" (computed as the engine writes it).
double number(const std::string& text) {
  const size_t slash = text.find('/');
  if (slash != std::string::npos) {
    return std::strtod(text.substr(0, slash).c_str(), nullptr) /
           std::strtod(text.substr(slash + 1).c_str(), nullptr);
  }
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  EXPECT_EQ(*end, '\0') << "not a number: '" << text << "'";
  return v;
}

TEST(SettingsDoc, DefaultsMatchTheEngine) {
  const std::map<std::string, std::string> rows = documented_defaults();
  v1::WorldSettings defaults;
  world_settings_to_proto(WorldSettings{}, &defaults);
  const pb::Descriptor& type = *defaults.GetDescriptor();
  const pb::Reflection& r = *defaults.GetReflection();
  for (int i = 0; i < type.field_count(); ++i) {
    const pb::FieldDescriptor& f = *type.field(i);
    auto row = rows.find(std::string(f.name()));
    if (row == rows.end()) {
      ADD_FAILURE() << f.name() << ": no row in docs/scenes.md";
      continue;
    }
    const std::string& doc = row->second;
    switch (f.cpp_type()) {
      case pb::FieldDescriptor::CPPTYPE_DOUBLE:
        EXPECT_EQ(number(doc), r.GetDouble(defaults, &f)) << f.name() << ": documented " << doc;
        break;
      case pb::FieldDescriptor::CPPTYPE_INT32:
        EXPECT_EQ(number(doc), r.GetInt32(defaults, &f)) << f.name() << ": documented " << doc;
        break;
      case pb::FieldDescriptor::CPPTYPE_BOOL:
        EXPECT_EQ(doc, r.GetBool(defaults, &f) ? "true" : "false") << f.name();
        break;
      case pb::FieldDescriptor::CPPTYPE_MESSAGE: {
        // A Vec2, documented as "(x, y)".
        ASSERT_EQ(f.message_type()->full_name(), "fulcrum.v1.Vec2") << f.name();
        const v1::Vec2& v = static_cast<const v1::Vec2&>(r.GetMessage(defaults, &f));
        const size_t comma = doc.find(',');
        ASSERT_TRUE(doc.front() == '(' && doc.back() == ')' && comma != std::string::npos)
            << f.name() << ": documented " << doc;
        EXPECT_EQ(number(doc.substr(1, comma - 1)), v.x()) << f.name() << ": documented " << doc;
        EXPECT_EQ(number(doc.substr(comma + 2, doc.size() - comma - 3)), v.y())
            << f.name() << ": documented " << doc;
        break;
      }
      default:
        ADD_FAILURE() << f.name() << ": a field type this test does not read";
    }
  }
  for (const auto& [name, value] : rows) {
    EXPECT_NE(type.FindFieldByName(name), nullptr)
        << "docs/scenes.md documents '" << name << "', which WorldSettings does not have";
  }
}

}  // namespace
}  // namespace fulcrum
