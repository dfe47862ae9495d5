// The path a request's target names, as the service's routes match it.
// httplib routes by its target's path as written, percent-decoded: a target
// in absolute-form (`GET http://HEAD:8080/api/jobs`), which RFC 9112 3.2.2
// has a server accept, was routed as the path "http://HEAD:8080/api/jobs"
// and answered 404; and "%2F" was decoded to a slash that routed as one, so
// an id segment "1%2Fcancel" reached the cancel of job 1.
#pragma once

#include <optional>
#include <string>

namespace rayfarm {

// The path of `target` (origin-form "/api/jobs?x", or absolute-form
// "http://HOST:PORT/api/jobs?x", the scheme in any case; its authority, like
// Host, names nothing the service tells apart), percent-decoded but for an
// encoded slash, kept as "%2F" (no route matches a path holding it). An
// absolute-form target without a path names "/". nullopt for an http target
// without a host ("http:///api/jobs"), which RFC 9110 4.2.1 has a recipient
// reject. Any other target (another scheme, "*") is decoded as a path, which
// no route matches.
std::optional<std::string> routed_path(const std::string& target);

}  // namespace rayfarm
