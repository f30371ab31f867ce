// A small result type for operations that fail for expected reasons (bad input, bad bytes).
// Exceptions are reserved for programming errors and the tool boundary (DEVELOPERS.md).
#pragma once

#include <cassert>
#include <cstdint>
#include <string>
#include <utility>
#include <variant>

namespace cfg {

/// What kind of failure an Error is, set where it arises, so that a caller (a tool choosing its
/// exit code) needs no checks of its own beforehand.
enum class ErrorCategory : std::uint8_t {
  Input,  ///< the input (text, bytes, a value, a command) is not what it must be
  Io,     ///< a file could not be opened, read or written (missing, a directory, no permission)
};

/// Why an operation failed, in words a user understands, and of which kind.
struct Error {
  std::string message;
  ErrorCategory category = ErrorCategory::Input;
  bool operator==(const Error&) const = default;
};

/// Either a T or an Error. Check `ok()` (or the bool conversion) before `value()`.
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : state_(std::move(value)) {}      // NOLINT(google-explicit-constructor)
  Result(Error error) : state_(std::move(error)) {}  // NOLINT(google-explicit-constructor)

  bool ok() const { return state_.index() == 0; }
  explicit operator bool() const { return ok(); }

  T& value() & {
    assert(ok());
    return std::get<0>(state_);
  }
  const T& value() const& {
    assert(ok());
    return std::get<0>(state_);
  }
  T&& value() && {
    assert(ok());
    return std::get<0>(std::move(state_));
  }
  const Error& error() const {
    assert(!ok());
    return std::get<1>(state_);
  }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

 private:
  std::variant<T, Error> state_;
};

/// Success or an Error, for operations with nothing to return.
template <>
class [[nodiscard]] Result<void> {
 public:
  Result() = default;
  Result(Error error)
      : error_(std::move(error)), ok_(false) {}  // NOLINT(google-explicit-constructor)

  bool ok() const { return ok_; }
  explicit operator bool() const { return ok_; }
  const Error& error() const {
    assert(!ok_);
    return error_;
  }

 private:
  Error error_;
  bool ok_ = true;
};

using Status = Result<void>;

}  // namespace cfg
