#include "store/sqlite_util.h"

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <system_error>
#include <utility>

namespace relief::store {
namespace {

std::string describe(sqlite3* db, int rc) {
  std::string message = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  // For file trouble the OS error says more than SQLite's generic text
  // ("unable to open database file").
  const int primary = rc & 0xff;
  if (db != nullptr && (primary == SQLITE_CANTOPEN || primary == SQLITE_IOERR || primary == SQLITE_FULL ||
                        primary == SQLITE_PERM)) {
    const int os_error = sqlite3_system_errno(db);
    if (os_error != 0) message += std::string(" (") + std::strerror(os_error) + ")";
  }
  return message;
}

}  // namespace

Status sqlite_error(sqlite3* db, int rc, const std::string& path, std::string_view what) {
  const std::string prefix = path + ": " + std::string(what) + ": ";
  switch (rc & 0xff) {
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      return io_error(prefix + "the archive is locked by another connection (waited " +
                      std::to_string(kBusyTimeoutMs / 1000) + " s): " + describe(db, rc));
    case SQLITE_NOTADB:
      return format_error(prefix + "not a SQLite database: " + describe(db, rc));
    case SQLITE_CORRUPT:
      return format_error(prefix + "the SQLite file is damaged: " + describe(db, rc));
    case SQLITE_TOOBIG:
      return limit_exceeded(prefix + describe(db, rc));
    case SQLITE_CONSTRAINT:
      // Relief validates what it writes, so a violated constraint means the
      // file's content contradicts the format (or another writer broke it).
      return format_error(prefix + describe(db, rc));
    case SQLITE_CANTOPEN:
    case SQLITE_IOERR:
    case SQLITE_FULL:
    case SQLITE_PERM:
    case SQLITE_READONLY:
    case SQLITE_PROTOCOL:
    case SQLITE_NOLFS:
      return io_error(prefix + describe(db, rc));
    default:
      return internal_error(prefix + describe(db, rc));
  }
}

std::string sqlite_file_name(const std::string& path) {
  if (path.rfind("file:", 0) == 0) return "./" + path;
  return path;
}

std::string immutable_uri(const std::string& path) {
  std::error_code ec;
  std::string absolute = std::filesystem::absolute(path, ec).string();
  if (ec) absolute = path;
  // RFC 3986 percent-encoding of everything but unreserved characters and
  // '/', so '?', '#', '%' or spaces in a name cannot change the URI's meaning.
  std::string uri = "file:";
  constexpr char kHex[] = "0123456789ABCDEF";
  for (const char c : absolute) {
    const auto byte = static_cast<unsigned char>(c);
    const bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '/' ||
                       c == '-' || c == '.' || c == '_' || c == '~';
    if (plain) {
      uri += c;
    } else {
      uri += '%';
      uri += kHex[byte >> 4];
      uri += kHex[byte & 0xf];
    }
  }
  return uri + "?mode=ro&immutable=1";
}

Result<Connection> open_connection(const std::string& file, int flags, const std::string& path,
                                   std::string_view what) {
  sqlite3* raw = nullptr;
  // NOMUTEX: a handle is used by one thread at a time (archive.h), so
  // SQLite's per-connection mutex would only cost time.
  const std::string name = (flags & SQLITE_OPEN_URI) != 0 ? file : sqlite_file_name(file);
  const int rc = sqlite3_open_v2(name.c_str(), &raw, flags | SQLITE_OPEN_NOMUTEX, nullptr);
  Connection connection(raw);  // sqlite3_open_v2 may return a handle even when it fails
  if (rc != SQLITE_OK) {
    if (raw == nullptr) return internal_error(path + ": " + std::string(what) + ": out of memory");
    return sqlite_error(raw, rc, path, what);
  }
  sqlite3_extended_result_codes(raw, 1);
  sqlite3_busy_timeout(raw, kBusyTimeoutMs);
  // An archive may come from anywhere: do not let its schema (triggers,
  // views) call functions with side effects, and refuse writes that corrupt
  // the file on purpose (shadow tables, writable_schema).
  sqlite3_db_config(raw, SQLITE_DBCONFIG_TRUSTED_SCHEMA, 0, static_cast<int*>(nullptr));
  sqlite3_db_config(raw, SQLITE_DBCONFIG_DEFENSIVE, 1, static_cast<int*>(nullptr));
  return connection;
}

Status close_connection(Connection connection, const std::string& path) {
  sqlite3* raw = connection.release();
  const int rc = sqlite3_close(raw);
  if (rc != SQLITE_OK) {
    Status status = sqlite_error(raw, rc, path, "close");
    sqlite3_close_v2(raw);  // hand it to SQLite to finish when it can
    return status;
  }
  return Status::ok();
}

std::string compact_sql(std::string_view sql) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; };
  const auto tight = [](char c) { return c == '(' || c == ')' || c == ',' || c == ';'; };
  std::string out;
  out.reserve(sql.size());
  char quote = 0;  // the open quote character, 0 outside quotes
  bool pending_space = false;
  for (const char c : sql) {
    if (quote != 0) {
      out.push_back(c);
      if (c == quote) quote = 0;  // a doubled quote closes and reopens: same text
      continue;
    }
    if (is_space(c)) {
      pending_space = true;
      continue;
    }
    if (pending_space && !out.empty() && !tight(out.back()) && !tight(c)) out.push_back(' ');
    pending_space = false;
    if (c == '\'' || c == '"' || c == '`') quote = c;
    out.push_back(c);
  }
  return out;
}

Status exec(sqlite3* db, const char* sql, const std::string& path, std::string_view what) {
  const int rc = sqlite3_exec(db, sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) return sqlite_error(db, rc, path, what);
  return Status::ok();
}

// ---- Statement

Statement::Statement(sqlite3* db, sqlite3_stmt* stmt, const std::string& path, std::string what)
    : db_(db), stmt_(stmt), path_(path), what_(std::move(what)) {}

Statement::~Statement() { sqlite3_finalize(stmt_); }

Result<std::unique_ptr<Statement>> Statement::prepare(sqlite3* db, std::string_view sql,
                                                      const std::string& path, std::string what) {
  sqlite3_stmt* stmt = nullptr;
  // PERSISTENT: these statements live as long as the connection and are
  // reused for every row, so SQLite should not take them from lookaside.
  const int rc = sqlite3_prepare_v3(db, sql.data(), static_cast<int>(sql.size()), SQLITE_PREPARE_PERSISTENT,
                                    &stmt, nullptr);
  if (rc != SQLITE_OK) {
    sqlite3_finalize(stmt);
    return sqlite_error(db, rc, path, what);
  }
  return std::unique_ptr<Statement>(new Statement(db, stmt, path, std::move(what)));
}

void Statement::note_bind(int rc) {
  if (rc != SQLITE_OK && bind_rc_ == SQLITE_OK) bind_rc_ = rc;
}

void Statement::bind_int64(int index, std::int64_t value) {
  note_bind(sqlite3_bind_int64(stmt_, index, value));
}

void Statement::bind_double(int index, double value) { note_bind(sqlite3_bind_double(stmt_, index, value)); }

void Statement::bind_text(int index, std::string_view value) {
  note_bind(sqlite3_bind_text64(stmt_, index, value.data(), value.size(), SQLITE_STATIC, SQLITE_UTF8));
}

void Statement::bind_blob(int index, const std::uint8_t* data, std::size_t size) {
  // sqlite3_bind_blob with a null pointer binds NULL, not an empty blob, and
  // an empty vector may well have data() == nullptr.
  if (size == 0) {
    note_bind(sqlite3_bind_zeroblob(stmt_, index, 0));
    return;
  }
  note_bind(sqlite3_bind_blob64(stmt_, index, data, size, SQLITE_STATIC));
}

void Statement::bind_null(int index) { note_bind(sqlite3_bind_null(stmt_, index)); }

Result<bool> Statement::step() {
  if (bind_rc_ != SQLITE_OK) {
    // The message of a failed bind is the connection's current error.
    return sqlite_error(db_, bind_rc_, path_, what_);
  }
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  return sqlite_error(db_, rc, path_, what_);
}

Status Statement::run() {
  for (;;) {
    RELIEF_ASSIGN_OR_RETURN(const bool row, step());
    if (!row) return Status::ok();
  }
}

void Statement::reset() {
  // The result of sqlite3_reset repeats the last step's error, already reported.
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
  bind_rc_ = SQLITE_OK;
}

int Statement::column_type(int column) const { return sqlite3_column_type(stmt_, column); }

std::int64_t Statement::column_int64(int column) const { return sqlite3_column_int64(stmt_, column); }

double Statement::column_double(int column) const { return sqlite3_column_double(stmt_, column); }

std::string Statement::column_text(int column) const {
  const unsigned char* text = sqlite3_column_text(stmt_, column);
  const int size = sqlite3_column_bytes(stmt_, column);
  if (text == nullptr || size <= 0) return {};
  return std::string(reinterpret_cast<const char*>(text), static_cast<std::size_t>(size));
}

Status Statement::column_bytes(int column, std::vector<std::uint8_t>& out) const {
  // Order matters: ask for the pointer first, then the size of that form.
  const void* data = sqlite3_column_blob(stmt_, column);
  const int size = sqlite3_column_bytes(stmt_, column);
  out.clear();
  if (size <= 0) return Status::ok();
  if (data == nullptr) return sqlite_error(db_, SQLITE_NOMEM, path_, what_);
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  out.assign(bytes, bytes + size);
  return Status::ok();
}

// ---- Transaction

Transaction::~Transaction() {
  // Some errors (SQLITE_FULL, SQLITE_IOERR, SQLITE_NOMEM, busy in COMMIT)
  // already rolled the transaction back; a second ROLLBACK would only fail.
  if (active_ && sqlite3_get_autocommit(db_) == 0) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }
}

Status Transaction::begin(Kind kind) {
  RELIEF_RETURN_IF_ERROR(
      exec(db_, kind == Kind::kWrite ? "BEGIN IMMEDIATE" : "BEGIN", path_, "begin transaction"));
  active_ = true;
  return Status::ok();
}

Status Transaction::commit() {
  RELIEF_RETURN_IF_ERROR(exec(db_, "COMMIT", path_, "commit"));
  active_ = false;
  return Status::ok();
}

namespace {

// The SQLite database header (sqlite.org/fileformat.html, section 1.3).
constexpr std::size_t kSqliteHeaderSize = 100;
constexpr char kSqliteMagic[] = "SQLite format 3";  // 16 bytes with its NUL
constexpr std::size_t kPageSizeOffset = 16;         // 2 bytes big-endian; 1 means 65536
constexpr std::size_t kChangeCounterOffset = 24;    // 4 bytes
constexpr std::size_t kPageCountOffset = 28;        // 4 bytes: database size in pages
constexpr std::size_t kVersionValidForOffset = 92;  // 4 bytes

std::uint32_t load_be32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | p[3];
}

}  // namespace

Status check_not_truncated(const std::string& path) {
  std::error_code ec;
  const auto file_size = std::filesystem::file_size(path, ec);
  if (ec) return Status::ok();  // open reports it
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return Status::ok();
  std::array<std::uint8_t, kSqliteHeaderSize> h{};
  const std::size_t got = std::fread(h.data(), 1, h.size(), f);
  std::fclose(f);
  if (got < h.size() || std::memcmp(h.data(), kSqliteMagic, sizeof kSqliteMagic) != 0) return Status::ok();
  const std::uint32_t raw_page = (std::uint32_t{h[kPageSizeOffset]} << 8) | h[kPageSizeOffset + 1];
  const std::uint64_t page_size = raw_page == 1 ? 65536 : raw_page;
  const std::uint32_t pages = load_be32(h.data() + kPageCountOffset);
  // The in-header size is valid only when the last writer that changed the
  // file also set it (older writers did not).
  if (load_be32(h.data() + kChangeCounterOffset) != load_be32(h.data() + kVersionValidForOffset)) {
    return Status::ok();
  }
  const std::uint64_t expected = page_size * pages;
  if (page_size < 512 || expected <= file_size) return Status::ok();
  return format_error(path + ": truncated: its SQLite header declares " + std::to_string(pages) + " pages of " +
                      std::to_string(page_size) + " bytes (" + std::to_string(expected) + " bytes) but the file has " +
                      std::to_string(file_size) + " bytes");
}

}  // namespace relief::store
