// The browser's token for the HTTP endpoint when server.auth.tokens_file is set: GET
// /login?token=<token> checks it and stores it in a cookie, which the browser then sends with the
// web map's page, tiles, /points and /events (same origin) without the page knowing the token.
// The cookie is HttpOnly (no script reads it), SameSite=Strict (no other site's page sends it),
// Secure over HTTPS, and lasts for the browser session.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace bgkmap {

// The cookie's name.
inline constexpr std::string_view kLoginCookieName = "bgkmap_token";

// The value of the `token` parameter of a request target ("/login?token=abc"), percent-decoded;
// empty if there is none.
std::string LoginTokenFromQuery(std::string_view target);

// The Set-Cookie header value that stores `token` (percent-encoded).
std::string LoginCookie(std::string_view token, bool secure);

// The token in a Cookie header value ("a=1; bgkmap_token=..."), decoded; none if absent.
std::optional<std::string> TokenFromCookies(std::string_view cookies);

}  // namespace bgkmap
