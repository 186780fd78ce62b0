"""Who may use the labelling page: the access token, the Host and Origin checks, the cookie.

Threats and what stops each (SECURITY.md says the same for users):
- another machine: beyond loopback a token is always required (one is made if none given);
- DNS rebinding (a web page whose name is re-pointed at 127.0.0.1): the Host header must
  name an address this server serves, on every mode, the token-less default included;
- cross-site requests from a page the annotator visits (another site, or another port on
  this machine): a foreign `Origin` or a cross-origin `Sec-Fetch-Site` is refused, so a
  page elsewhere can neither read nor write; writes must be JSON (checked in `limits.py`);
- forged log lines: a refused request's path, method and headers are logged escaped
  (`loggable`), so a request (a cross-site image is enough to send one) can neither
  start a new line in the operator's terminal nor send it control characters;
- the token leaking: `?token=` is accepted on the page address only, traded there for an
  HttpOnly, SameSite=Strict cookie (the page then drops it from the address bar); the
  cookie holds a value derived from the token, not the token, and its name carries the
  port, so two servers on one machine keep their own. Browsers send cookies to every port
  of a host: a service on another port of this machine can still receive it;
- acting as another (a team's page): a request carrying two credentials is the person whose
  token it presents, in the address or the header, never the cookie's (`identify`).
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import ipaddress
import logging
import secrets
import socket
import string
import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import lru_cache

from starlette.datastructures import Headers
from starlette.requests import HTTPConnection
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

MIN_TOKEN_LENGTH = 16
TOKEN_CHARACTERS = frozenset(string.ascii_letters + string.digits + "-_.~")  # URL-safe as is
TOKEN_HEADER = "x-seqrank-token"
LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
SECURITY_HEADERS = [
    (
        b"content-security-policy",
        b"default-src 'self'; media-src 'self' blob:; frame-ancestors 'none'; base-uri 'none'",
    ),
    (b"x-frame-options", b"DENY"),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
    (b"cross-origin-resource-policy", b"same-origin"),
]
log = logging.getLogger(__name__)
LIMITED_BROADCAST = ipaddress.IPv4Address("255.255.255.255")


def loggable(value: str, limit: int = 200) -> str:
    """A value from a request as it may go into the log: at most `limit` characters, with
    control characters, non-ASCII and backslashes escaped (`\\x1b`, `\\n`, `\\u202e`)."""
    return value[:limit].encode("unicode_escape").decode("ascii")


def log_refusal(method: str, path: str, status: int, detail: str) -> None:
    """One line per refused request: method, path, status and reason, never the body."""
    shown = (loggable(method, 20), loggable(path), status, loggable(detail, 300))
    log.warning("refused %s %s (%d): %s", *shown)


def is_loopback(host: str) -> bool:
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def is_wildcard(host: str) -> bool:
    """0.0.0.0 or ::, which listen on every address of the machine."""
    try:
        return ipaddress.ip_address(host).is_unspecified
    except ValueError:
        return False


def page_token(host: str, token: str | None) -> str | None:
    """The token the page requires: the given one, a new one beyond loopback, or none.

    Raises ValueError (one line, for the CLI) for a token that is empty, too short to guard
    a page other machines can reach, or not typeable in an address as it is.
    """
    if token is None:
        return None if is_loopback(host) else secrets.token_urlsafe(24)
    beyond = not is_loopback(host)
    if not token or (beyond and len(token) < MIN_TOKEN_LENGTH):
        where = f"--host {host} lets other machines connect" if beyond else "it is empty"
        raise ValueError(
            f"--token of {len(token)} characters refused: {where}; give at least "
            f"{MIN_TOKEN_LENGTH} (letters, digits, - _ . ~) or leave --token out to have one made"
        )
    if not set(token) <= TOKEN_CHARACTERS:
        raise ValueError("--token: use letters, digits and - _ . ~ only (it goes in an address)")
    return token


def host_name(host_header: str) -> str | None:
    """The name or address in a Host header, without the port; None if malformed."""
    value = host_header.strip().lower()
    if value.startswith("["):
        name, bracket, rest = value[1:].partition("]")
        if not bracket or (rest and not rest[1:].isdigit()) or (rest and rest[0] != ":"):
            return None
    else:
        name, _, port = value.partition(":")
        if ":" in port or (port and not port.isdigit()):
            return None
    name = name.rstrip(".")
    return name or None


@lru_cache(maxsize=1)
def subnet_edges() -> frozenset[ipaddress.IPv4Address]:
    """The network and broadcast addresses of this machine's IPv4 subnets (Linux; empty
    where the interfaces cannot be asked). A socket binds to a subnet's broadcast address,
    but no host is reached by it."""
    try:
        import fcntl
    except ImportError:  # not a POSIX system
        return frozenset()
    get_address, get_netmask = 0x8915, 0x891B  # SIOCGIFADDR, SIOCGIFNETMASK
    edges: set[ipaddress.IPv4Address] = set()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        for _, interface in socket.if_nameindex():
            request = struct.pack("256s", interface.encode()[:15])
            with contextlib.suppress(OSError):  # an interface without an IPv4 address
                address = fcntl.ioctl(probe.fileno(), get_address, request)[20:24]
                netmask = fcntl.ioctl(probe.fileno(), get_netmask, request)[20:24]
                network = ipaddress.IPv4Network(
                    (socket.inet_ntoa(address), socket.inet_ntoa(netmask)), strict=False
                )
                if network.prefixlen < 31:  # /31 and /32 have no network or broadcast
                    edges |= {network.network_address, network.broadcast_address}
    return frozenset(edges)


@lru_cache(maxsize=256)
def is_local_address(name: str) -> bool:
    """Whether `name` is an IP address of this machine (it can be bound to, and it is
    not a broadcast or a subnet's network address)."""
    try:
        address = ipaddress.ip_address(name)
    except ValueError:
        return False
    if address.is_unspecified or address.is_multicast:
        return False
    if address == LIMITED_BROADCAST or address in subnet_edges():
        return False
    family = socket.AF_INET6 if address.version == 6 else socket.AF_INET
    with socket.socket(family, socket.SOCK_DGRAM) as probe:
        try:
            probe.bind((str(address), 0))
        except OSError:
            return False
    return True


OPERATOR = "(operator)"  # who holds the main token when a team has tokens of its own


@dataclass(frozen=True)
class Access:
    """What the guard accepts: the token (if any) and the names the server is reached by.
    A team's page (`--annotators`) also accepts each annotator's own token, and tells the
    routes whose it was (`who`): the main token is then the operator's."""

    token: str | None
    names: frozenset[str]  # lower-case host names and addresses, without the port
    any_local_address: bool  # a wildcard bind: every address of this machine is served
    cookie: str  # the session cookie's name
    annotator_tokens: tuple[tuple[str, str], ...] = ()  # (annotator, token)

    @classmethod
    def serving(
        cls,
        host: str,
        port: int,
        token: str | None,
        extra_names: Iterable[str] = (),
        annotator_tokens: Iterable[tuple[str, str]] = (),
    ) -> Access:
        wildcard = is_wildcard(host)
        names = {n.lower().rstrip(".") for n in extra_names}
        if not wildcard:  # nobody opens http://0.0.0.0/: a wildcard stands for the rest
            names.add(host.lower())
        if wildcard or is_loopback(host):
            names |= LOOPBACK_NAMES
        if wildcard:
            names |= {socket.gethostname().lower(), socket.getfqdn().lower()}
        team = tuple(annotator_tokens)
        return cls(token, frozenset(names), wildcard, f"seqrank_session_{port}", team)

    def serves(self, name: str) -> bool:
        return name in self.names or (self.any_local_address and is_local_address(name))

    def session_value(self, token: str | None = None) -> str:
        """The cookie's value: derived from the token, so the cookie never holds the token."""
        token = token if token is not None else self.token
        assert token is not None
        return hmac.new(token.encode(), b"seqrank page session", hashlib.sha256).hexdigest()

    def holders(self) -> list[tuple[str | None, str]]:
        """(who, token) of every token accepted: the main one's holder is None for one
        person's page and the operator on a team's."""
        assert self.token is not None
        main = OPERATOR if self.annotator_tokens else None
        return [(main, self.token), *self.annotator_tokens]


@dataclass(frozen=True)
class Verdict:
    status: int = 0  # 0: allowed
    detail: str = ""
    set_cookie: str | None = None  # the address carried this token: trade it for the cookie
    who: str | None = None  # on a team's page: the annotator (or OPERATOR) it belongs to


def check_origin(method: str, headers: Headers, scheme: str = "http") -> str | None:
    """Why a request from another origin is refused (None: same origin, or not a browser).
    `scheme`: the request's own (`http`, `https`, or `ws`, `wss` for a WebSocket); an
    origin must match it and the Host, so a page served over https elsewhere on this
    host and port is another origin."""
    origin = headers.get("origin")
    if origin is not None:
        own_scheme = {"ws": "http", "wss": "https"}.get(scheme, scheme)
        origin_scheme, _, authority = origin.partition("://")
        if origin_scheme != own_scheme or authority.lower() != headers["host"].lower():
            return f"requests from {origin[:100]!r} are refused: use the page itself"
    site = headers.get("sec-fetch-site", "none")
    if site in ("same-origin", "none"):
        return None
    # a link from elsewhere may open the page (the person sees it, the other site does not)
    navigation = headers.get("sec-fetch-mode") == "navigate"
    if method in ("GET", "HEAD") and navigation and headers.get("sec-fetch-dest") == "document":
        return None
    return "requests from other pages are refused: use the page itself"


def check_request(access: Access, request: HTTPConnection, method: str = "GET") -> Verdict:
    """The guard's decision for one request (or WebSocket handshake, a GET): Host, then
    Origin, then the token."""
    name = host_name(request.headers.get("host", ""))
    if name is None or not access.serves(name):
        shown = request.headers.get("host", "")[:100]
        return Verdict(
            400,
            f"Host {shown!r} is not an address this server serves; open the address it printed "
            "(or start it with --allow-host NAME for another name of this machine)",
        )
    refused = check_origin(method, request.headers, request.url.scheme)
    if refused is not None:
        return Verdict(403, refused)
    if access.token is None:
        return Verdict()
    return identify(access, request)


PAGES = ("/", "/operator")  # the addresses that take `?token=` (and trade it for the cookie)
UNKNOWN = "missing or wrong access token: open the address the server printed"


def identify(access: Access, request: HTTPConnection) -> Verdict:
    """Whose request it is. A token the request presents (in a page's address, or in the
    header) decides, over the cookie: a wrong one is refused even beside a valid cookie,
    and the cookie is re-issued when it is not the winner's. An address and a header that
    give two different tokens are refused (400): neither is taken over the other. The
    cookie alone decides only when no token is presented."""
    from_address = request.query_params.get("token") if request.scope["path"] in PAGES else None
    header = request.headers.get(TOKEN_HEADER)
    cookie = request.cookies.get(access.cookie)
    if from_address is not None and header is not None and not _same(from_address, header):
        return Verdict(
            400,
            "the request carries two different tokens, in the address and in the "
            f"{TOKEN_HEADER} header: send one",
        )
    given = from_address if from_address is not None else header
    if given is None:
        found = _holder(access, cookie, access.session_value) if cookie is not None else None
        return Verdict(401, UNKNOWN) if found is None else Verdict(who=found[0])
    found = _holder(access, given, lambda token: token)
    if found is None:
        return Verdict(401, UNKNOWN)
    who, token = found
    stale = cookie is not None and not _same(cookie, access.session_value(token))
    reissue = from_address is not None or stale  # the address's is always traded for one
    return Verdict(set_cookie=token if reissue else None, who=who)


def _holder(
    access: Access, given: str, credential: Callable[[str], str]
) -> tuple[str | None, str] | None:
    """(who, token) of the holder whose `credential(token)` is `given`; None: nobody's.
    Every holder is compared, in constant time each."""
    found = None
    for who, token in access.holders():
        if _same(given, credential(token)) and found is None:
            found = (who, token)
    return found


def _same(given: str, expected: str) -> bool:
    return secrets.compare_digest(given.encode(errors="replace"), expected.encode(errors="replace"))


class AccessGuard:
    """ASGI middleware: every request and WebSocket handshake passes `check_request`; every
    reply gets the security headers (no framing, no cross-origin embedding, no referrer).
    Only the server's own lifespan events pass unchecked."""

    def __init__(self, app: ASGIApp, access: Access):
        self.app, self.access = app, access

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "lifespan":
            await self.app(scope, receive, send)
            return
        if scope["type"] != "http":
            await self._websocket(scope, receive, send)
            return
        verdict = check_request(self.access, HTTPConnection(scope), scope["method"])
        extra = list(SECURITY_HEADERS)
        if verdict.set_cookie is not None:
            extra.append((b"set-cookie", self._cookie_header(verdict.set_cookie)))
        scope.setdefault("state", {})["who"] = verdict.who

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                message["headers"] = [*message.get("headers", []), *extra]
            await send(message)

        if verdict.status:
            log_refusal(scope["method"], scope["path"], verdict.status, verdict.detail)
            response = JSONResponse({"detail": verdict.detail}, verdict.status)
            await response(scope, receive, send_with_headers)
            return
        await self.app(scope, receive, send_with_headers)

    async def _websocket(self, scope: Scope, receive: Receive, send: Send) -> None:
        """A WebSocket handshake gets the same checks (the page opens none: the app then
        refuses it itself); anything else is refused outright."""
        if scope["type"] != "websocket":
            raise RuntimeError(f"unsupported ASGI scope {loggable(str(scope['type']), 40)}")
        verdict = check_request(self.access, HTTPConnection(scope))
        if not verdict.status:
            scope.setdefault("state", {})["who"] = verdict.who
            await self.app(scope, receive, send)
            return
        log_refusal("WEBSOCKET", scope["path"], verdict.status, verdict.detail)
        await receive()  # the handshake's websocket.connect
        await send({"type": "websocket.close", "code": 1008})  # policy violation

    def _cookie_header(self, token: str) -> bytes:
        value = self.access.session_value(token)
        return f"{self.access.cookie}={value}; Path=/; HttpOnly; SameSite=Strict".encode()
