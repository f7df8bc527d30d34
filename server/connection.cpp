#include "server/connection.h"

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <fcntl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <climits>

namespace server {
namespace {

std::string openSslReason() {
  const unsigned long code = ERR_get_error();
  ERR_clear_error();
  if (code == 0) return "no reason given";
  char text[256];
  ERR_error_string_n(code, text, sizeof text);
  return text;
}

// The outcome of an SSL_* call that returned `rc` <= 0.
IoResult tlsOutcome(SSL* tls, int rc) {
  IoResult out;
  switch (SSL_get_error(tls, rc)) {
    case SSL_ERROR_WANT_READ: out.kind = IoResult::Kind::kWantRead; break;
    case SSL_ERROR_WANT_WRITE: out.kind = IoResult::Kind::kWantWrite; break;
    case SSL_ERROR_ZERO_RETURN: out.kind = IoResult::Kind::kClosed; break;
    case SSL_ERROR_SYSCALL:
      // EOF without close_notify, or a socket error: the client is gone.
      out.kind = errno == EAGAIN || errno == EWOULDBLOCK ? IoResult::Kind::kWantRead : IoResult::Kind::kClosed;
      ERR_clear_error();
      break;
    default:
      out.kind = IoResult::Kind::kFailed;
      out.error = openSslReason();
  }
  return out;
}

IoResult socketOutcome(ssize_t n, IoResult::Kind would_block) {
  IoResult out;
  if (n > 0) {
    out.kind = IoResult::Kind::kBytes;
    out.bytes = static_cast<std::size_t>(n);
  } else if (n == 0) {
    out.kind = IoResult::Kind::kClosed;
  } else if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) {
    out.kind = would_block;
  } else {
    out.kind = IoResult::Kind::kFailed;
  }
  return out;
}

}  // namespace

core::Result<std::shared_ptr<TlsContext>> TlsContext::load(const std::filesystem::path& certificate_chain,
                                                            const std::filesystem::path& private_key) {
  const auto invalid = [](const std::string& message) { return core::makeError(core::ErrorCode::kInvalidArgument, message); };
  ERR_clear_error();
  SSL_CTX* context = SSL_CTX_new(TLS_server_method());
  if (!context) return invalid("TLS: cannot create a context: " + openSslReason());
  std::shared_ptr<TlsContext> out(new TlsContext(context));
  // TLS 1.2 and 1.3 only; no renegotiation (a client could make the server
  // redo the expensive half of a handshake at will).
  SSL_CTX_set_min_proto_version(context, TLS1_2_VERSION);
  SSL_CTX_set_options(context, SSL_OP_NO_RENEGOTIATION | SSL_OP_CIPHER_SERVER_PREFERENCE);
  // Partial writes: httplib's writer loops until all is sent, and a blocked
  // write is retried from wherever its buffer then is.
  SSL_CTX_set_mode(context, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
  if (SSL_CTX_use_certificate_chain_file(context, certificate_chain.c_str()) != 1) {
    return invalid("TLS certificate '" + certificate_chain.string() + "': " + openSslReason());
  }
  // Loading the key checks it against the certificate loaded above.
  if (SSL_CTX_use_PrivateKey_file(context, private_key.c_str(), SSL_FILETYPE_PEM) != 1) {
    if (ERR_GET_REASON(ERR_peek_last_error()) == X509_R_KEY_VALUES_MISMATCH) {
      return invalid("TLS private key '" + private_key.string() + "' does not belong to the certificate '" +
                     certificate_chain.string() + "'");
    }
    return invalid("TLS private key '" + private_key.string() + "': " + openSslReason());
  }
  return out;
}

TlsContext::~TlsContext() { SSL_CTX_free(context_); }

SSL* TlsContext::newSession(int fd) const {
  SSL* tls = SSL_new(context_);
  if (!tls) return nullptr;
  if (SSL_set_fd(tls, fd) != 1) {
    SSL_free(tls);
    return nullptr;
  }
  SSL_set_accept_state(tls);
  return tls;
}

Connection::Connection(int fd, SSL* tls) : fd_(fd), tls_(tls), established_(tls == nullptr) {
  // OpenSSL reads and writes the socket with plain read(2)/write(2): in
  // blocking mode (as httplib accepts it, with a receive timeout) a call
  // with nothing to read would stall the gate's thread.
  const int flags = fcntl(fd_, F_GETFL, 0);
  if (flags >= 0) fcntl(fd_, F_SETFL, flags | O_NONBLOCK);
}

Connection::~Connection() { close(); }

IoResult Connection::handshake() {
  if (established_) return {IoResult::Kind::kBytes, 0, {}};
  ERR_clear_error();
  const int rc = SSL_do_handshake(tls_);
  if (rc == 1) {
    established_ = true;
    return {IoResult::Kind::kBytes, 0, {}};
  }
  return tlsOutcome(tls_, rc);
}

IoResult Connection::receive(char* data, std::size_t size) {
  if (!tls_) return socketOutcome(::recv(fd_, data, size, MSG_DONTWAIT), IoResult::Kind::kWantRead);
  ERR_clear_error();
  const int rc = SSL_read(tls_, data, static_cast<int>(std::min<std::size_t>(size, INT_MAX)));
  if (rc > 0) return {IoResult::Kind::kBytes, static_cast<std::size_t>(rc), {}};
  return tlsOutcome(tls_, rc);
}

IoResult Connection::send(const char* data, std::size_t size) {
  if (!tls_) {
    IoResult out = socketOutcome(::send(fd_, data, size, MSG_NOSIGNAL | MSG_DONTWAIT), IoResult::Kind::kWantWrite);
    if (out.kind == IoResult::Kind::kClosed) out.kind = IoResult::Kind::kWantWrite;  // 0 bytes sent: try again
    return out;
  }
  ERR_clear_error();
  const int rc = SSL_write(tls_, data, static_cast<int>(std::min<std::size_t>(size, INT_MAX)));
  if (rc > 0) return {IoResult::Kind::kBytes, static_cast<std::size_t>(rc), {}};
  return tlsOutcome(tls_, rc);
}

bool Connection::hasPending() const { return tls_ && SSL_pending(tls_) > 0; }

void Connection::close() {
  if (fd_ < 0) return;
  if (tls_) {
    if (established_) {
      ERR_clear_error();
      SSL_shutdown(tls_);  // sends close_notify if the socket takes it now
    }
    SSL_free(tls_);
    tls_ = nullptr;
  }
  ::shutdown(fd_, SHUT_RDWR);
  ::close(fd_);
  fd_ = -1;
}

}  // namespace server
