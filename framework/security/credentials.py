"""Zenoh user/password authentication: credentials files and their settings (docs/security.md).

A credentials file holds one ``user:password`` per line; blank lines and lines starting with ``#``
are ignored.  The graph's hub gets every entry as its Zenoh dictionary (written to a private file
of the launcher), and authenticates with its own user like its node processes and the tools
(``--credentials FILE --user NAME``).  Passwords never appear in graph files or on command lines.
"""

from __future__ import annotations

import logging
import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path

from ..network.settings import UsrPwdSettings

log = logging.getLogger("handflow.credentials")
_USER = re.compile(r"^[A-Za-z0-9_.@\-]+$")
FORMAT = "one 'user:password' per line (user: letters, digits, '_', '-', '.', '@'; '#' starts a comment line)"


class CredentialsError(ValueError):
    """A credentials file that cannot be used; the text says where and what to change."""


@dataclass(frozen=True)
class Credentials:
    """The entries of a credentials file (user → password)."""

    path: Path
    users: dict[str, str]

    def login(self, user: str | None, how: str = "--user NAME") -> tuple[str, str]:
        """(user, password) for ``user``, or for the only user of the file when None (else say ``how``)."""
        if user is None:
            if len(self.users) > 1:
                raise CredentialsError(f"{self.path} holds several users ({', '.join(self.users)}); pass {how}")
            user = next(iter(self.users))
        if user not in self.users:
            raise CredentialsError(f"{self.path} has no user '{user}'; add a line '{user}:PASSWORD'")
        return user, self.users[user]

    def __repr__(self) -> str:  # never print passwords
        return f"Credentials({str(self.path)!r}, users={sorted(self.users)})"


def parse_credentials(text: str, source: str = "<credentials>") -> dict[str, str]:
    """user → password from the text of a credentials file, or :class:`CredentialsError` (``source:line``)."""
    users: dict[str, str] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        user, sep, password = line.partition(":")
        where = f"{source}:{number}"
        if not sep or not _USER.match(user):
            raise CredentialsError(f"{where}: expected {FORMAT}")
        if not password or not password.isprintable() or password != password.strip():
            raise CredentialsError(
                f"{where}: the password of '{user}' must be non-empty printable text without surrounding spaces"
            )
        if user in users:
            raise CredentialsError(f"{where}: user '{user}' appears twice; keep one line per user")
        users[user] = password
    if not users:
        raise CredentialsError(f"{source}: no credentials; write {FORMAT}")
    return users


def read_credentials(path: str | Path, warn_shared: bool = False) -> Credentials:
    """The credentials file at ``path``, or :class:`CredentialsError` saying what to change.

    ``warn_shared`` logs a warning when other users may read the file.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise CredentialsError(f"credentials file {path} does not exist; create it with {FORMAT}") from None
    except UnicodeDecodeError:
        raise CredentialsError(f"credentials file {path} is not UTF-8 text; write {FORMAT}") from None
    except OSError as exc:
        raise CredentialsError(f"cannot read credentials file {path}: {exc.strerror}") from None
    except ValueError:  # a NUL byte or lone surrogate in the name
        raise CredentialsError(f"{str(path)!r} is not a usable file name; name the credentials file") from None
    creds = Credentials(path, parse_credentials(text, str(path)))
    if warn_shared and path.stat().st_mode & (stat.S_IRWXG | stat.S_IRWXO):
        log.warning("credentials file %s is readable by other users; restrict it with `chmod 600 %s`", path, path)
    return creds


def graph_credentials(usrpwd: UsrPwdSettings, base_dir: Path, host: str | None) -> tuple[Credentials, str]:
    """A graph's credentials (``usrpwd`` of the graph file in ``base_dir``) and this machine's user
    (``usrpwd.user``, else ``run --host``, else the only user)."""
    creds = read_credentials(base_dir / usrpwd.credentials, warn_shared=True)
    user = usrpwd.user or (host if host in creds.users else None)
    return creds, creds.login(user, "`handflow run --host NAME` or set 'zenoh: {usrpwd: {user: NAME}}'")[0]


def write_dictionary(creds: Credentials, directory: str | Path) -> Path:
    """Zenoh's ``dictionary_file`` (bare ``user:password`` lines), readable by this user only."""
    path = Path(directory) / "zenoh-dictionary"
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.writelines(f"{u}:{p}\n" for u, p in creds.users.items())
    return path


def usrpwd_settings(creds: Credentials, user: str, dictionary: Path | None = None) -> dict[str, str]:
    """``transport/auth/usrpwd/*`` values: this side's login, plus the dictionary it checks others against."""
    settings = {"user": user, "password": creds.users[user]}
    if dictionary is not None:
        settings["dictionary_file"] = str(dictionary)
    return settings
