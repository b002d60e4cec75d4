// MappingConfig with every field by its "section.key" name; the gcmap package adds one attribute
// per section on top (config.preprocess.downsample).
#include <pybind11/stl.h>

#include "arrays.hpp"
#include "bindings.hpp"
#include "gcmap/mapping/config.hpp"

namespace gcmap::python {

namespace {

// Sets every entry of a flat ("section.key": value) or nested ({section: {key: value}}) dict.
void set_all(MappingConfig& config, const py::dict& values, const std::string& prefix = "") {
  for (const auto& [name, value] : values) {
    const std::string key = prefix + py::str(name).cast<std::string>();
    if (py::isinstance<py::dict>(value)) set_all(config, value.cast<py::dict>(), key + ".");
    else config.set(key, value.cast<MappingConfig::Value>());
  }
}

// Applies the values to a copy and keeps it only when the whole config is valid.
void update(MappingConfig& config, const py::dict& values) {
  MappingConfig changed = config;
  set_all(changed, values);
  changed.validate();
  config = changed;
}

py::dict to_dict(const MappingConfig& config) {
  py::dict out;
  for (const std::string& key : MappingConfig::keys()) {
    const size_t dot = key.find('.');
    const py::str section(key.substr(0, dot));
    if (!out.contains(section)) out[section] = py::dict();
    out[section].cast<py::dict>()[py::str(key.substr(dot + 1))] = py::cast(config.get(key));
  }
  return out;
}

}  // namespace

void bind_config(py::module_& m) {
  py::class_<MappingConfig>(m, "MappingConfig", R"(Every parameter of the mapping system, with the paper's defaults.

Sections (preprocess, odometry, local, global, loop, output) are attributes whose fields are
attributes too: config.preprocess.downsample = 0.5. The same by name: config["global.mode"],
config.set("global.mode", "sliding-window"), or MappingConfig({"local": {"max_keyframes": 10}}).
Every change is validated; a bad name, type or value raises ValueError naming the key and leaves
the config as it was. to_yaml() / from_yaml() / load() round-trip the YAML config of `gcmap map`.)")
      .def(py::init([](py::object values) {
             MappingConfig c;
             if (!values.is_none()) update(c, values.cast<py::dict>());
             return c;
           }),
           py::arg("values") = py::none(), "Defaults, changed by a flat {\"section.key\": v} or nested {section: {key: v}} dict.")
      .def_static("keys", &MappingConfig::keys, "Every field as \"section.key\", in YAML order.")
      .def("get", &MappingConfig::get, py::arg("key"), "The value of \"section.key\" (enums as their names).")
      .def(
          "set",
          [](MappingConfig& c, const std::string& key, const MappingConfig::Value& value) {
            update(c, py::dict(py::arg(key.c_str()) = py::cast(value)));
          },
          py::arg("key"), py::arg("value"), "Sets \"section.key\"; ValueError naming the key if the result is invalid.")
      .def("__getitem__", &MappingConfig::get)
      .def("__setitem__", [](MappingConfig& c, const std::string& key,
                             const MappingConfig::Value& value) { update(c, py::dict(py::arg(key.c_str()) = py::cast(value))); })
      .def("update", &update, py::arg("values"), "Sets every entry of a flat or nested dict, all or none.")
      .def("to_dict", &to_dict, "A nested dict {section: {key: value}}.")
      .def("validate", &MappingConfig::validate, "Raises ValueError naming the first invalid key.")
      .def("to_yaml", &MappingConfig::to_yaml, "Every field as YAML text, as `gcmap map` reads it.")
      .def_static(
          "from_yaml", [](const std::string& text) { return MappingConfig::parse(text, "config"); }, py::arg("text"),
          "Parses YAML text (missing keys keep their defaults); ValueError naming a bad or unknown key.")
      .def_static(
          "load", [](const std::string& path) { return with_file(path, [&] { return MappingConfig::load(path); }); },
          py::arg("path"), "Reads a YAML file; FileNotFoundError when it is missing, ValueError naming a bad key.")
      .def("copy", [](const MappingConfig& c) { return c; })
      .def("__copy__", [](const MappingConfig& c) { return c; })
      .def("__deepcopy__", [](const MappingConfig& c, py::dict) { return c; })
      .def(
          "__eq__", [](const MappingConfig& a, const MappingConfig& b) { return a.to_yaml() == b.to_yaml(); }, py::is_operator())
      .def("__repr__", [](const MappingConfig& c) {
        const MappingConfig defaults;
        std::string changed;
        for (const std::string& key : MappingConfig::keys())
          if (c.get(key) != defaults.get(key))
            changed += (changed.empty() ? "" : ", ") + ("'" + key + "': " + py::repr(py::cast(c.get(key))).cast<std::string>());
        return "MappingConfig({" + changed + "})";
      });
}

}  // namespace gcmap::python
