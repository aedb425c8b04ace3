#include "sc_rt/law_registry.hpp"

#include <dlfcn.h>
#include <elf.h>
#include <fcntl.h>
#include <limits.h>
#include <link.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <map>
#include <mutex>

namespace sc_rt {

const char* const kDefaultLaw = "dsc-ppc";
const char* const kPluginPrefix = "plugin:";
const char* const kPythonPrefix = "python:";

// The built-in laws, each registered by its own file (in this order: the
// codes 0..3 of controller_status_t.law).
void register_dsc_laws();  // law_dsc.cpp: dsc-ppc, dsc
void register_pd_law();    // law_pd.cpp: pd
void register_rft_law();   // law_rft.cpp: rft

namespace {

struct Registry {
  std::recursive_mutex mu;
  std::vector<LawEntry> entries;
  std::map<std::string, std::string> loaded;  // real path -> law name
  std::map<std::string, LawEntry> python;     // "python:..." spec -> its entry
  bool builtins = false;
};

Registry& registry() {
  static Registry r;
  std::lock_guard<std::recursive_mutex> lock(r.mu);
  if (!r.builtins) {
    r.builtins = true;
    register_dsc_laws();
    register_pd_law();
    register_rft_law();
  }
  return r;
}

const LawEntry* find(Registry& r, const std::string& name) {
  for (const LawEntry& e : r.entries)
    if (e.name == name) return &e;
  return nullptr;
}

bool is_file(const std::string& p) {
  struct stat st;
  return ::stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

// Why a plugin path given by the user is no file to load: missing, a
// symlink loop, a directory, a device or a FIFO.
std::string not_a_file(const std::string& p) {
  struct stat st;
  if (::stat(p.c_str(), &st) != 0)
    return errno == ELOOP ? "a symlink loop (too many levels of symbolic links): " + p : "no such file " + p;
  return p + " is not a regular file";
}

std::string fail_prefix(const std::string& spec) { return std::string("law ") + kPluginPrefix + spec + ": "; }

[[noreturn]] void fail(const std::string& spec, const std::string& detail) {
  throw LawError("law", fail_prefix(spec) + detail, detail);
}

// The file of a plugin spec: a path (it has a '/' or ends in .so), else a
// name searched in SCRT_LAW_PATH.
std::string locate(const std::string& spec) {
  const bool path = spec.find('/') != std::string::npos ||
                    (spec.size() > 3 && spec.compare(spec.size() - 3, 3, ".so") == 0);
  if (path) {
    if (!is_file(spec)) fail(spec, not_a_file(spec));
    return spec;
  }
  const char* env = std::getenv("SCRT_LAW_PATH");
  const std::string dirs = env ? env : "";
  std::size_t a = 0;
  while (a <= dirs.size()) {
    std::size_t b = dirs.find(':', a);
    if (b == std::string::npos) b = dirs.size();
    const std::string d = dirs.substr(a, b - a);
    if (!d.empty())
      for (const std::string& f : {d + "/lib" + spec + ".so", d + "/" + spec + ".so"})
        if (is_file(f)) return f;
    a = b + 1;
  }
  fail(spec, "not found: no lib" + spec + ".so or " + spec + ".so in SCRT_LAW_PATH (" +
                 (dirs.empty() ? std::string("unset") : dirs) + ")");
}

// Reads exactly n bytes at offset off (false: a short read or an error).
bool read_at(int fd, void* buf, std::size_t n, std::uint64_t off) {
  auto* p = static_cast<char*>(buf);
  while (n > 0) {
    const ssize_t got = ::pread(fd, p, n, static_cast<off_t>(off));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return false;
    p += got;
    n -= static_cast<std::size_t>(got);
    off += static_cast<std::uint64_t>(got);
  }
  return true;
}

// Whether the file range [off, off + len) lies within size bytes (overflow-safe).
bool within(std::uint64_t off, std::uint64_t len, std::uint64_t size) { return off <= size && len <= size - off; }

std::string range(std::uint64_t off, std::uint64_t len) {
  return "bytes " + std::to_string(off) + ".." + std::to_string(off + len);
}

}  // namespace

std::string plugin_file_problem(const std::string& path) {
  using Ehdr = ElfW(Ehdr);
  using Phdr = ElfW(Phdr);
  using Shdr = ElfW(Shdr);
  // O_NONBLOCK: opening a FIFO does not wait for a writer (it is refused below).
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return std::string("cannot open it: ") + std::strerror(errno);
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st;
  if (::fstat(fd, &st) != 0) return std::string("cannot stat it: ") + std::strerror(errno);
  if (!S_ISREG(st.st_mode)) return "not a regular file";
  const auto size = static_cast<std::uint64_t>(st.st_size);
  const std::string of_size = " ends beyond the file's " + std::to_string(size) + " bytes: the file is truncated or damaged";
  Ehdr eh;
  if (size < sizeof eh || !read_at(fd, &eh, sizeof eh, 0))
    return "not a shared library: " + std::to_string(size) + " bytes, shorter than an ELF header";
  if (std::memcmp(eh.e_ident, ELFMAG, SELFMAG) != 0) return "not a shared library (no ELF header)";
  const unsigned char cls = sizeof(void*) == 8 ? ELFCLASS64 : ELFCLASS32;
  if (eh.e_ident[EI_CLASS] != cls)
    return std::string("an ELF file of the other word size (") +
           (eh.e_ident[EI_CLASS] == ELFCLASS32 ? "32" : eh.e_ident[EI_CLASS] == ELFCLASS64 ? "64" : "unknown") +
           "-bit), this process is " + std::to_string(8 * sizeof(void*)) + "-bit";
#if __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  const unsigned char data = ELFDATA2LSB;
#else
  const unsigned char data = ELFDATA2MSB;
#endif
  if (eh.e_ident[EI_DATA] != data) return "an ELF file of the other byte order";
  if (eh.e_type != ET_DYN) return "not a shared library (ELF type " + std::to_string(eh.e_type) + ")";
  // The section header table (optional for the loader; a linker writes it at the end of the file).
  std::uint64_t shnum = eh.e_shnum;
  std::vector<Shdr> sh;
  if (eh.e_shoff != 0) {
    if (eh.e_shentsize != sizeof(Shdr)) return "a section header size of " + std::to_string(eh.e_shentsize) + " bytes";
    Shdr first;
    if (!within(eh.e_shoff, sizeof first, size) || !read_at(fd, &first, sizeof first, eh.e_shoff))
      return "its section header table (from byte " + std::to_string(eh.e_shoff) + ")" + of_size;
    if (shnum == 0) shnum = first.sh_size;  // more than SHN_LORESERVE sections: the count is there
    if (shnum > size / sizeof(Shdr) || !within(eh.e_shoff, shnum * sizeof(Shdr), size))
      return "its section header table (" + range(eh.e_shoff, shnum * sizeof(Shdr)) + ")" + of_size;
    sh.resize(shnum);
    if (!read_at(fd, sh.data(), shnum * sizeof(Shdr), eh.e_shoff)) return "cannot read its section headers";
    for (std::uint64_t i = 0; i < shnum; ++i)
      if (sh[i].sh_type != SHT_NOBITS && sh[i].sh_type != SHT_NULL && !within(sh[i].sh_offset, sh[i].sh_size, size))
        return "its section " + std::to_string(i) + " (" + range(sh[i].sh_offset, sh[i].sh_size) + ")" + of_size;
  }
  // The program header table and every segment the loader maps.
  std::uint64_t phnum = eh.e_phnum;
  if (phnum == PN_XNUM && !sh.empty()) phnum = sh[0].sh_info;  // more than 65534 segments
  if (phnum == 0) return "not a shared library (no program headers)";
  if (eh.e_phentsize != sizeof(Phdr)) return "a program header size of " + std::to_string(eh.e_phentsize) + " bytes";
  if (phnum > size / sizeof(Phdr) || !within(eh.e_phoff, phnum * sizeof(Phdr), size))
    return "its program header table (" + range(eh.e_phoff, phnum * sizeof(Phdr)) + ")" + of_size;
  std::vector<Phdr> ph(phnum);
  if (!read_at(fd, ph.data(), phnum * sizeof(Phdr), eh.e_phoff)) return "cannot read its program headers";
  bool load = false;
  for (std::uint64_t i = 0; i < phnum; ++i) {
    if (ph[i].p_type != PT_LOAD && ph[i].p_type != PT_DYNAMIC) continue;
    load = load || ph[i].p_type == PT_LOAD;
    const char* kind = ph[i].p_type == PT_LOAD ? "PT_LOAD" : "PT_DYNAMIC";
    if (!within(ph[i].p_offset, ph[i].p_filesz, size))
      return "its segment " + std::to_string(i) + " (" + kind + ", " + range(ph[i].p_offset, ph[i].p_filesz) + ")" +
             of_size;
    if (ph[i].p_type == PT_LOAD && ph[i].p_filesz > ph[i].p_memsz)
      return "its segment " + std::to_string(i) + " (PT_LOAD) has more bytes in the file than in memory";
  }
  if (!load) return "not a shared library (no loadable segment)";
  return "";
}

void register_law(const std::string& name, const std::string& doc, LawFactory create,
                  LawParams::Items defaults) {
  // Also called by the built-ins from inside registry() (recursive mutex).
  Registry& reg = registry();
  std::lock_guard<std::recursive_mutex> lock(reg.mu);
  if (name.empty() || name.find(':') != std::string::npos || name.find('/') != std::string::npos)
    throw std::invalid_argument("law name must be non-empty without ':' or '/', got \"" + name + "\"");
  if (const LawEntry* e = find(reg, name))
    throw std::invalid_argument("law \"" + name + "\" is already registered (" + e->source + ")");
  LawEntry e;
  e.name = name;
  e.doc = doc;
  e.source = "built-in";
  e.code = static_cast<int>(reg.entries.size());
  e.create = std::move(create);
  e.defaults = std::move(defaults);
  reg.entries.push_back(std::move(e));
}

const char* law_command_name(LawCommand c) {
  return c == LawCommand::Torque ? "torque" : "acceleration";
}

void register_python_law(const std::string& spec, const std::string& name, const std::string& doc,
                         LawFactory create, LawCommand command) {
  Registry& reg = registry();
  std::lock_guard<std::recursive_mutex> lock(reg.mu);
  const std::size_t n = std::strlen(kPythonPrefix);
  if (spec.compare(0, n, kPythonPrefix) != 0 || spec.size() == n)
    throw std::invalid_argument("a Python law's spec starts with \"python:\", got \"" + spec + "\"");
  if (name.empty()) throw std::invalid_argument("law " + spec + ": empty name");
  LawEntry e;
  e.name = name;
  e.doc = doc;
  e.source = spec;
  e.code = -1;
  e.create = std::move(create);
  e.command = command;
  reg.python[spec] = std::move(e);
}

void clear_python_laws() {
  Registry& reg = registry();
  std::lock_guard<std::recursive_mutex> lock(reg.mu);
  reg.python.clear();
}

std::vector<std::string> law_names() {
  Registry& r = registry();
  std::lock_guard<std::recursive_mutex> lock(r.mu);
  std::vector<std::string> out;
  for (const LawEntry& e : r.entries) out.push_back(e.name);
  return out;
}

std::string load_law_plugin(const std::string& spec) {
  Registry& r = registry();
  std::lock_guard<std::recursive_mutex> lock(r.mu);
  const std::string file = locate(spec);
  char buf[PATH_MAX];
  const std::string real = ::realpath(file.c_str(), buf) ? std::string(buf) : file;
  if (auto it = r.loaded.find(real); it != r.loaded.end()) return it->second;
  // A damaged file is refused here: dlopen maps it, and a segment that ends
  // beyond a truncated file's end kills the process (SIGBUS) when touched.
  if (const std::string problem = plugin_file_problem(real); !problem.empty())
    fail(spec, "cannot load " + real + ": " + problem);
  // RTLD_NOW: an unresolved symbol is reported here, not mid-run.
  void* h = ::dlopen(real.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!h) {
    const char* err = ::dlerror();
    fail(spec, "cannot load " + real + ": " + (err ? err : "dlopen failed"));
  }
  using VersionFn = int (*)();
  using InfoFn = const LawPluginInfo* (*)();
  auto version = reinterpret_cast<VersionFn>(::dlsym(h, SC_RT_LAW_ENTRY_VERSION));
  if (!version) {
    ::dlclose(h);
    fail(spec, real + " has no " SC_RT_LAW_ENTRY_VERSION "(): not an sc-rt law plugin "
                      "(SC_RT_LAW_PLUGIN(...) in one source file, docs/LAWS.md)");
  }
  const int v = version();
  if (v != SC_RT_LAW_API_VERSION) {
    ::dlclose(h);
    fail(spec, "built against law interface version " + std::to_string(v) +
                   ", this sc-rt has " + std::to_string(SC_RT_LAW_API_VERSION) +
                   ": rebuild it against this sc-rt (-DCMAKE_PREFIX_PATH=$(sc-rt --cmake-dir))");
  }
  auto info_fn = reinterpret_cast<InfoFn>(::dlsym(h, SC_RT_LAW_ENTRY_INFO));
  const LawPluginInfo* info = info_fn ? info_fn() : nullptr;
  if (!info || !info->create || !info->name || !info->fingerprint) {
    ::dlclose(h);
    fail(spec, real + " has no usable " SC_RT_LAW_ENTRY_INFO "(): not an sc-rt law plugin");
  }
  if (std::strcmp(info->fingerprint, SC_RT_LAW_FINGERPRINT) != 0) {
    const std::string fp = info->fingerprint;
    ::dlclose(h);
    fail(spec, "built with \"" + fp + "\", this sc-rt has \"" SC_RT_LAW_FINGERPRINT
                   "\": rebuild it with the same compiler and flags");
  }
  // Revision 1: what the law commands (optional; none: wheel accelerations).
  using CommandFn = int (*)();
  LawCommand command = LawCommand::Acceleration;
  if (auto command_fn = reinterpret_cast<CommandFn>(::dlsym(h, SC_RT_LAW_ENTRY_COMMAND))) {
    const int c = command_fn();
    if (c != static_cast<int>(LawCommand::Acceleration) && c != static_cast<int>(LawCommand::Torque)) {
      ::dlclose(h);
      fail(spec, real + ": " SC_RT_LAW_ENTRY_COMMAND "() returned " + std::to_string(c) +
                     ", not a LawCommand (0 acceleration, 1 torque)");
    }
    command = static_cast<LawCommand>(c);
  }
  const std::string name = info->name;
  if (const LawEntry* e = find(r, name)) {
    ::dlclose(h);
    fail(spec, "its law name \"" + name + "\" is already registered (" + e->source + ")");
  }
  // The library stays loaded for the process's lifetime (laws may outlive any handle).
  auto create = info->create;
  register_law(name, info->doc ? info->doc : "", [create](const LawSetup& s) {
    return std::unique_ptr<ControlLaw>(create(s));
  });
  r.entries.back().source = real;
  r.entries.back().command = command;
  r.loaded[real] = name;
  return name;
}

LawEntry resolve_law(const std::string& spec) {
  Registry& r = registry();
  std::lock_guard<std::recursive_mutex> lock(r.mu);
  const std::size_t n = std::strlen(kPluginPrefix);
  std::string name = spec;
  if (spec.compare(0, std::strlen(kPythonPrefix), kPythonPrefix) == 0) {
    if (auto it = r.python.find(spec); it != r.python.end()) return it->second;
    const std::string detail = "law " + spec +
                               ": a Python law runs in a process that loaded it (sc-rt sim, sc-rt controller); "
                               "it is not loaded here";
    throw LawError("law", detail, detail);
  }
  if (spec.compare(0, n, kPluginPrefix) == 0) {
    if (spec.size() == n) fail("", "empty plugin path or name");
    name = load_law_plugin(spec.substr(n));
  }
  const LawEntry* e = find(r, name);
  if (!e) {
    std::string known;
    for (const LawEntry& x : r.entries) known += (known.empty() ? "" : ", ") + x.name;
    const std::string detail = "unknown law \"" + spec + "\" (registered: " + known +
                               "; a plugin: plugin:PATH_OR_NAME)";
    throw LawError("law", detail, detail);
  }
  return *e;
}

}  // namespace sc_rt
