// `--set NAME=VALUE`: world settings overridden from the command line by their field names in
// proto/fulcrum/v1/scene.proto (WorldSettings), found by protobuf reflection so that every
// field works, nested ones too ("gravity.y"). Ranges are checked by the scene conversion
// (world_settings_from_proto), the same check a scene file or the server's CreateWorld gets.
#pragma once

#include <string>
#include <vector>

#include "fulcrum/status.h"
#include "fulcrum/types.h"

namespace fulcrum::cli {

// One "NAME=VALUE" item, split but not yet applied.
struct SettingOverride {
  std::string text;   // as given, for messages
  std::string field;  // "substeps", "gravity.y" (proto or JSON names)
  std::string value;  // "6", "-9.81", "true"
};

// Splits each item at its first '='. Errors name the item.
Result<std::vector<SettingOverride>> parse_setting_overrides(const std::vector<std::string>& items);

// Applies the overrides in order to *settings: the settings go to their proto form, each field
// is set there, and the whole is read back through world_settings_from_proto, which checks
// every range. On error *settings is unchanged and the message names the item and the field:
// "--set substeps=0: settings.substeps: must be >= 1 (got 0)", "--set substep=6: WorldSettings
// has no field 'substep'", "--set dt=fast: dt: expected a number, got 'fast'".
Status apply_setting_overrides(const std::vector<SettingOverride>& overrides,
                               WorldSettings* settings);

}  // namespace fulcrum::cli
