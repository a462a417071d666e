// The index of each mapping, chosen by what the mapping is: a planar mapping (planar.hpp) gets
// the planar index, an axial one (axial.hpp) the curved index. AnyIndex holds the index of any
// mapping in AnyMapping's list (any_mapping.hpp), in the same order, so a mapping added there has
// its index, its tree files and its place in every tool that takes AnyIndex with no other edit.
#pragma once

#include <variant>

#include "qota/any_mapping.hpp"
#include "qota/curved.hpp"
#include "qota/terrain.hpp"

namespace qota {

namespace detail {
template <class M>
struct IndexOf;
template <PlanarMapping M>
struct IndexOf<M> {
  using type = PlanarIndex<M>;
};
template <AxialMapping M>
struct IndexOf<M> {
  using type = CurvedIndex<M>;
};
template <class Mappings>
struct IndexesOf;
template <class... M>
struct IndexesOf<std::variant<M...>> {
  using type = std::variant<typename IndexOf<M>::type...>;
};
}  // namespace detail

template <class M>
using IndexFor = typename detail::IndexOf<M>::type;

// AnyIndex's alternative i is the index of AnyMapping's alternative i.
using AnyIndex = typename detail::IndexesOf<AnyMapping>::type;

}  // namespace qota
