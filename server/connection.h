// One accepted client connection, as the gate and the HTTP threads see it:
// its socket and, behind a TLS listener (--tls-cert/--tls-key), its TLS
// session. Every read and write is non-blocking; the caller waits (poll or
// epoll) in the direction the last call asked for. A TLS handshake is driven
// the same way, so a client that stalls it holds no thread (the gate waits
// for it as for a slow request head).
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>

#include "core/base/error.h"

typedef struct ssl_st SSL;
typedef struct ssl_ctx_st SSL_CTX;

namespace server {

// The server's certificate chain and private key (PEM files), loaded once.
class TlsContext {
 public:
  // The error (kInvalidArgument) names the file at fault and OpenSSL's reason.
  static core::Result<std::shared_ptr<TlsContext>> load(const std::filesystem::path& certificate_chain,
                                                         const std::filesystem::path& private_key);
  ~TlsContext();
  TlsContext(const TlsContext&) = delete;
  TlsContext& operator=(const TlsContext&) = delete;
  SSL* newSession(int fd) const;  // nullptr when OpenSSL cannot make one

 private:
  explicit TlsContext(SSL_CTX* context) : context_(context) {}
  SSL_CTX* context_;
};

// What a non-blocking call did: moved bytes (> 0), found the peer closed
// (0), would block until the socket is readable or writable, or failed.
struct IoResult {
  enum class Kind { kBytes, kClosed, kWantRead, kWantWrite, kFailed };
  Kind kind = Kind::kFailed;
  std::size_t bytes = 0;
  std::string error;  // kFailed on TLS: OpenSSL's reason
};

class Connection {
 public:
  // Takes ownership of `fd` (and of `tls`, a session on it, when given).
  Connection(int fd, SSL* tls);
  ~Connection();  // close()
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  int fd() const { return fd_; }
  bool established() const { return established_; }  // plain, or its TLS handshake is done
  // Advances the TLS handshake: kBytes (0 bytes) once done, kWant* while it
  // waits for the client, kFailed / kClosed when it cannot complete.
  IoResult handshake();
  IoResult receive(char* data, std::size_t size);
  IoResult send(const char* data, std::size_t size);
  // Decrypted bytes already held by the TLS session: readable without the
  // socket being so.
  bool hasPending() const;
  // TLS close_notify (best effort, not waited on), then the socket closed.
  void close();

 private:
  int fd_;
  SSL* tls_;
  bool established_;
};

}  // namespace server
