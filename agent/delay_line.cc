#include "agent/delay_line.h"

namespace mapmesh {

bool DelayLine::Room(std::size_t bytes) {
  if (held_.size() + 1 > options_.max_messages || bytes_ + bytes > options_.max_bytes) {
    ++dropped_;
    return false;
  }
  return true;
}

bool DelayLine::Hold(double arrival, MapMessage map, std::string writer, std::size_t bytes) {
  if (!Room(bytes)) return false;
  bytes_ += bytes;
  held_.emplace(std::pair{arrival, next_++}, HeldMap{std::move(map), std::move(writer), bytes});
  return true;
}

bool DelayLine::Hold(double arrival, const Sighting& sighting) {
  if (!Room(0)) return false;
  held_.emplace(std::pair{arrival, next_++}, sighting);
  return true;
}

std::vector<DelayLine::Message> DelayLine::TakeArrived(double now) {
  std::vector<Message> out;
  while (!held_.empty() && held_.begin()->first.first <= now) {
    auto node = held_.extract(held_.begin());
    if (const auto* m = std::get_if<HeldMap>(&node.mapped())) bytes_ -= m->bytes;
    out.push_back(std::move(node.mapped()));
  }
  return out;
}

}  // namespace mapmesh
