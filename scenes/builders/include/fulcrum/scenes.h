// Scene builders shared by tests, benchmarks and the CLI. Each appends bodies to a SceneDef;
// the named scenes are the cases of the hard-case table and the benchmark table.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "fulcrum/scene.h"
#include "fulcrum/status.h"

namespace fulcrum::scenes {

// A static box ground whose top surface is at y = top, spanning x in [-half_width, half_width].
void add_ground(SceneDef* scene, double half_width, double top = 0.0, double friction = 0.6);

struct PyramidOptions {
  int base = 20;               // boxes in the bottom row, >= 1
  double box_size = 1.0;       // edge length, m
  double spacing = 1.0;        // horizontal centre distance within a row, m (>= box_size)
  Vec2 origin = Vec2::Zero();  // centre of the bottom row's bottom edge, m
  double density = 1.0;        // kg/m^2
  double friction = 0.6;
  double top_density = -1.0;  // density of the top box; < 0 means `density`
};
// Rows from the bottom up; row r has base - r boxes resting exactly on the row below.
void add_pyramid(SceneDef* scene, const PyramidOptions& options);

struct StackOptions {
  int count = 20;              // boxes, >= 1
  double box_size = 1.0;       // m
  double offset = 0.01;        // sideways offset, alternately +offset and -offset, m
  Vec2 origin = Vec2::Zero();  // centre of the bottom box's bottom edge, m
  double density = 1.0;
  double friction = 0.6;
};
void add_stack(SceneDef* scene, const StackOptions& options);

// Named scenes (HARD_CASES.md and the benchmark table), ground included.
std::vector<std::string> builtin_names();
Result<SceneDef> builtin(std::string_view name);

}  // namespace fulcrum::scenes
