#include "set_settings.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include <charconv>
#include <limits>
#include <string_view>

#include "args.h"
#include "scene_convert.h"

namespace fulcrum::cli {
namespace {

namespace pb = google::protobuf;

// A field of `type` by its proto name ("joint_hertz") or its JSON name ("jointHertz").
const pb::FieldDescriptor* find_field(const pb::Descriptor& type, const std::string& name) {
  if (const pb::FieldDescriptor* f = type.FindFieldByName(name)) return f;
  return type.FindFieldByCamelcaseName(name);
}

// A decimal number, or a fraction "1/120" (a time step is easier to give as one).
Status parse_double(const std::string& text, double* out) {
  const auto whole = [](std::string_view part, double* v) {
    const char* end = part.data() + part.size();
    auto [ptr, ec] = std::from_chars(part.data(), end, *v);
    return !part.empty() && ec == std::errc() && ptr == end;
  };
  const size_t slash = text.find('/');
  double num = 0.0, den = 1.0;
  if (!whole(std::string_view(text).substr(0, slash), &num) ||
      (slash != std::string::npos && !whole(std::string_view(text).substr(slash + 1), &den))) {
    return invalid_argument("expected a number, got '" + text + "'");
  }
  *out = slash == std::string::npos ? num : num / den;
  return {};
}

// Sets the scalar `field` of `message` from `text`, parsed as the field's type.
Status set_scalar(pb::Message* message, const pb::FieldDescriptor& field, const std::string& text) {
  const pb::Reflection& r = *message->GetReflection();
  std::string error;
  switch (field.cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_DOUBLE:
    case pb::FieldDescriptor::CPPTYPE_FLOAT: {
      double v = 0.0;
      FULCRUM_RETURN_IF_ERROR(parse_double(text, &v));
      if (field.cpp_type() == pb::FieldDescriptor::CPPTYPE_DOUBLE) {
        r.SetDouble(message, &field, v);
      } else {
        r.SetFloat(message, &field, static_cast<float>(v));
      }
      return {};
    }
    case pb::FieldDescriptor::CPPTYPE_INT32:
    case pb::FieldDescriptor::CPPTYPE_INT64: {
      const bool is32 = field.cpp_type() == pb::FieldDescriptor::CPPTYPE_INT32;
      std::optional<int64_t> v = parse_int(
          text, is32 ? std::numeric_limits<int32_t>::min() : std::numeric_limits<int64_t>::min(),
          is32 ? std::numeric_limits<int32_t>::max() : std::numeric_limits<int64_t>::max(), &error);
      if (!v) return invalid_argument(error);
      if (is32) {
        r.SetInt32(message, &field, static_cast<int32_t>(*v));
      } else {
        r.SetInt64(message, &field, *v);
      }
      return {};
    }
    case pb::FieldDescriptor::CPPTYPE_UINT32:
    case pb::FieldDescriptor::CPPTYPE_UINT64: {
      // parse_int stops at INT64_MAX: enough for every count and mask in the settings.
      const bool is32 = field.cpp_type() == pb::FieldDescriptor::CPPTYPE_UINT32;
      std::optional<int64_t> v = parse_int(
          text, 0,
          is32 ? std::numeric_limits<uint32_t>::max() : std::numeric_limits<int64_t>::max(),
          &error);
      if (!v) return invalid_argument(error);
      if (is32) {
        r.SetUInt32(message, &field, static_cast<uint32_t>(*v));
      } else {
        r.SetUInt64(message, &field, static_cast<uint64_t>(*v));
      }
      return {};
    }
    case pb::FieldDescriptor::CPPTYPE_BOOL:
      if (text != "true" && text != "false" && text != "1" && text != "0") {
        return invalid_argument("expected true or false, got '" + text + "'");
      }
      r.SetBool(message, &field, text == "true" || text == "1");
      return {};
    case pb::FieldDescriptor::CPPTYPE_ENUM: {
      const pb::EnumValueDescriptor* v = field.enum_type()->FindValueByName(text);
      if (v == nullptr)
        return invalid_argument("no value '" + text + "' in " + field.enum_type()->name());
      r.SetEnum(message, &field, v);
      return {};
    }
    case pb::FieldDescriptor::CPPTYPE_STRING:
      r.SetString(message, &field, text);
      return {};
    case pb::FieldDescriptor::CPPTYPE_MESSAGE:
      break;
  }
  // A whole message ("gravity") has no one-word value; its fields do.
  std::string fields;
  for (int i = 0; i < field.message_type()->field_count(); ++i) {
    fields += (i > 0 ? ", " : "") + std::string(field.name()) + "." +
              std::string(field.message_type()->field(i)->name());
  }
  return invalid_argument("is a message: set its fields (" + fields + ")");
}

// Sets the field at the dotted `path` of `message`, creating the messages on the way.
Status set_path(pb::Message* message, const std::string& path, const std::string& text) {
  std::string walked;
  size_t start = 0;
  while (true) {
    const size_t dot = path.find('.', start);
    const std::string name = path.substr(start, dot == std::string::npos ? dot : dot - start);
    const pb::Descriptor& type = *message->GetDescriptor();
    const pb::FieldDescriptor* field = find_field(type, name);
    if (field == nullptr) {
      return invalid_argument((walked.empty() ? std::string(type.name()) : walked) +
                              " has no field '" + name + "'");
    }
    walked += (walked.empty() ? "" : ".") + std::string(field->name());
    if (field->is_repeated()) return invalid_argument(walked + ": a list; not settable here");
    if (dot == std::string::npos)
      return set_scalar(message, *field, text).with_prefix(walked + ": ");
    if (field->cpp_type() != pb::FieldDescriptor::CPPTYPE_MESSAGE) {
      return invalid_argument(walked + " is a " + std::string(field->cpp_type_name()) +
                              ", not a message: it has no field '" + path.substr(dot + 1) + "'");
    }
    message = message->GetReflection()->MutableMessage(message, field);
    start = dot + 1;
  }
}

}  // namespace

Result<std::vector<SettingOverride>> parse_setting_overrides(
    const std::vector<std::string>& items) {
  std::vector<SettingOverride> out;
  for (const std::string& item : items) {
    const size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0) {
      return invalid_argument("--set " + item + ": expected NAME=VALUE (e.g. substeps=6)");
    }
    out.push_back({item, item.substr(0, eq), item.substr(eq + 1)});
  }
  return out;
}

Status apply_setting_overrides(const std::vector<SettingOverride>& overrides,
                               WorldSettings* settings) {
  v1::WorldSettings proto;
  world_settings_to_proto(*settings, &proto);
  WorldSettings updated = *settings;
  // Checked after each item: the settings before it were in range, so a refusal is its field.
  for (const SettingOverride& o : overrides) {
    const std::string item = "--set " + o.text + ": ";
    FULCRUM_RETURN_IF_ERROR(set_path(&proto, o.field, o.value).with_prefix(item));
    FULCRUM_RETURN_IF_ERROR(
        world_settings_from_proto(proto, "settings", &updated).with_prefix(item));
  }
  *settings = updated;
  return {};
}

}  // namespace fulcrum::cli
