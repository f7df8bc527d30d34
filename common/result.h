// rigport::Result<T, E>: a value or the error that prevented it. The one
// spelling of "value or error" in every layer: core::Result<T> carries a
// core::Error, api::Parsed<T> the name of a malformed field, api::Result<T>
// (server and client) a problem+json Problem. Modelled on cpp-httplib's
// Result: check it (`if (!r) ... r.error()`) before reading the value.
// Header only, no dependencies: every layer may include it.
#pragma once

#include <cassert>
#include <type_traits>
#include <utility>
#include <variant>

namespace rigport {

template <typename T, typename E>
class Result {
  static_assert(!std::is_same_v<T, E>, "a value and its error are told apart by their types");

 public:
  Result(T value) : state_(std::in_place_index<0>, std::move(value)) {}  // NOLINT: implicit by design
  Result(E error) : state_(std::in_place_index<1>, std::move(error)) {}  // NOLINT: implicit by design

  bool ok() const { return state_.index() == 0; }
  explicit operator bool() const { return ok(); }

  const T& value() const& { assert(ok()); return std::get<0>(state_); }
  T& value() & { assert(ok()); return std::get<0>(state_); }
  T&& value() && { assert(ok()); return std::get<0>(std::move(state_)); }
  const T& operator*() const& { return value(); }
  T& operator*() & { return value(); }
  T&& operator*() && { return std::move(*this).value(); }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }

  const E& error() const { assert(!ok()); return std::get<1>(state_); }

 private:
  std::variant<T, E> state_;
};

// The value of operations that return nothing on success.
struct Ok {};

}  // namespace rigport
