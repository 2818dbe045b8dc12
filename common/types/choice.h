#pragma once
// Named choices: the values of an enum with the names scenarios, logs and output files use.
// A table lists each value once, in the order error messages name them; parsing and printing
// both go through it, so a choice is parsed once, where it is read, and compared as an enum.

#include <array>
#include <cstddef>
#include <optional>
#include <string_view>

namespace mapmesh {

template <typename E>
struct ChoiceName {
  E value;
  std::string_view name;
};

template <typename E, std::size_t N>
using ChoiceTable = std::array<ChoiceName<E>, N>;

// The name of v in table ("unknown" when the table lacks it).
template <typename E, std::size_t N>
constexpr std::string_view NameOf(const ChoiceTable<E, N>& table, E v) {
  for (const ChoiceName<E>& c : table) {
    if (c.value == v) return c.name;
  }
  return "unknown";
}

// The value named name; nullopt for a name the table lacks.
template <typename E, std::size_t N>
constexpr std::optional<E> ParseChoice(const ChoiceTable<E, N>& table, std::string_view name) {
  for (const ChoiceName<E>& c : table) {
    if (c.name == name) return c.value;
  }
  return std::nullopt;
}

}  // namespace mapmesh
