// The law registry (docs/LAWS.md section 2): names -> factories. The
// built-in laws register themselves (cpp/src/law_*.cpp); a plugin library is
// loaded (dlopen) and checked (interface version, ABI fingerprint) by
// load_law_plugin and registers the name it declares. Thread-safe.
#pragma once
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "sc_rt/law.hpp"

namespace sc_rt {

//! The law of a default ControllerConfig (the paper's).
extern const char* const kDefaultLaw;
//! The prefix of a plugin spec: "plugin:PATH_OR_NAME".
extern const char* const kPluginPrefix;
//! The prefix of a Python law's spec ("python:file.py:Class"): a law hosted by
//! the Python interpreter of the process (sc_rt.pylaw registers it through the
//! bindings); a process without one (sc-rt-controller) cannot resolve it.
extern const char* const kPythonPrefix;

using LawFactory = std::function<std::unique_ptr<ControlLaw>(const LawSetup&)>;

struct LawEntry {
  std::string name;    //!< registry name
  std::string doc;     //!< one line
  std::string source;  //!< "built-in" or the plugin library's path
  int code = -1;       //!< registry order (controller_status_t.law)
  LawFactory create;
  //! Its parameters and their defaults (a built-in law declares them: the
  //! values it uses for a key its table does not give; empty for a plugin)
  LawParams::Items defaults;
  //! What its u_cmd is: a plugin's sc_rt_law_command() (acceleration when it
  //! exports none), a Python law's class attribute command; the built-ins
  //! command wheel accelerations
  LawCommand command = LawCommand::Acceleration;
};

//! "acceleration" or "torque" (what a scenario's [wheels] command and a
//! Python law's command attribute say).
const char* law_command_name(LawCommand c);

// A bad law spec, plugin or parameter. key(): "law" or "params.<key>";
// detail(): the problem without the law's name (what() has both).
class LawError : public std::invalid_argument {
 public:
  LawError(std::string key, const std::string& what, std::string detail)
      : std::invalid_argument(what), key_(std::move(key)), detail_(std::move(detail)) {}
  const std::string& key() const { return key_; }
  const std::string& detail() const { return detail_; }

 private:
  std::string key_, detail_;
};

// Register a law under a new name (std::invalid_argument if taken), with
// the defaults of its parameters.
void register_law(const std::string& name, const std::string& doc, LawFactory create,
                  LawParams::Items defaults = {});
// Register a Python law under its whole spec ("python:..."), or replace the
// factory of a spec registered before (the same spec, loaded again). Its
// entry: name (the law's label, its table's name), source = spec, code -1
// (not a registry code: controller_info_t carries the name).
void register_python_law(const std::string& spec, const std::string& name, const std::string& doc,
                         LawFactory create, LawCommand command = LawCommand::Acceleration);
// Forget every Python law (the interpreter that hosts them is going away).
void clear_python_laws();
// Every registered name, registry order (the built-ins first).
std::vector<std::string> law_names();
// The entry of a registered name, of "plugin:PATH_OR_NAME" (loaded on
// first use) or of a registered "python:..." spec. Throws LawError.
LawEntry resolve_law(const std::string& spec);
// Load a plugin library (a path, or a name searched in SCRT_LAW_PATH as
// libNAME.so / NAME.so); returns its law name. Loading the same file again
// returns the same name. Throws LawError naming the plugin and the problem.
std::string load_law_plugin(const std::string& path_or_name);
// Why the file at path cannot be a loadable plugin ("" when it can), read
// before dlopen maps it: a regular file, an ELF shared library of this
// process's word size and byte order, its program and section header tables
// and every PT_LOAD/PT_DYNAMIC segment's file range within the file (a
// truncated library mapped by dlopen dies of SIGBUS when a page past the
// end is touched). Does not load or run anything.
std::string plugin_file_problem(const std::string& path);

}  // namespace sc_rt
