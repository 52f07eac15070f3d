#include "flexopt/core/log.hpp"

#include <map>
#include <mutex>
#include <string>

namespace flexopt {

PetscLogEvent log_event(const char *name) {
  static std::mutex lock;
  static std::map<std::string, PetscLogEvent> events;
  static PetscClassId class_id = 0;
  std::lock_guard<std::mutex> guard(lock);
  if (!class_id) PetscClassIdRegister("flexopt", &class_id);
  auto it = events.find(name);
  if (it != events.end()) return it->second;
  PetscLogEvent e = 0;
  PetscLogEventRegister(name, class_id, &e);
  events.emplace(name, e);
  return e;
}

} // namespace flexopt
