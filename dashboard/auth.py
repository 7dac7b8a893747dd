"""Who may use the dashboard: 127.0.0.1 by default; another address only with a sign-in token.

``.streamlit/config.toml`` binds the server to 127.0.0.1. Serving on another address
(``streamlit run app.py --server.address 0.0.0.0``) is opt-in: the operator sets
``WORKBENCH_DASHBOARD_TOKEN`` and every visitor signs in with their name and that token
before any page runs (:func:`gate`, called by ``app.py``). Without a token the dashboard
refuses to serve anything on a non-loopback address. With a token it asks for it on
127.0.0.1 too. The signed-in name is the operator recorded by approvals (:func:`operator`).
"""

from __future__ import annotations

import hmac
import ipaddress
import os

import streamlit as st

TOKEN_ENV = "WORKBENCH_DASHBOARD_TOKEN"
_OPERATOR = "auth.operator"


def is_loopback(address: str) -> bool:
    """Whether the server address reaches this machine only (127.0.0.0/8, ::1, localhost); '' = every interface."""
    if address.strip().lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(address.strip().strip("[]")).is_loopback
    except ValueError:
        return False  # '' (all interfaces), a host name or anything else: reachable from the network


def policy(address: str, token: str | None) -> str:
    """``"open"`` (loopback, no token), ``"sign-in"`` (a token is configured) or ``"refuse"``."""
    if token:
        return "sign-in"
    return "open" if is_loopback(address) else "refuse"


def token_matches(given: str, token: str) -> bool:
    """Constant-time comparison of the typed token with the configured one."""
    return hmac.compare_digest(given.encode(), token.encode())


def operator() -> str | None:
    """The signed-in operator's name, or None when the dashboard is open on 127.0.0.1 without sign-in."""
    return st.session_state.get(_OPERATOR)


def gate() -> None:
    """Stop the script run unless the visitor may see the dashboard (call before any page runs)."""
    address = str(st.get_option("server.address") or "")
    token = os.environ.get(TOKEN_ENV) or None
    rule = policy(address, token)
    if rule == "open" or (rule == "sign-in" and operator()):
        return
    if rule == "refuse":
        st.error(f"The dashboard is served on {address or 'every interface'}, not 127.0.0.1: set "
                 f"{TOKEN_ENV} so that visitors sign in (docs/dashboard.md). Nothing is shown until then.")
        st.stop()
    st.title("Sign in")
    with st.form("auth.form"):
        name = st.text_input("Operator name", key="auth.name")
        given = st.text_input("Access token", type="password", key="auth.token")
        submitted = st.form_submit_button("Sign in")
    if submitted:
        if name.strip() and token_matches(given, token):
            st.session_state[_OPERATOR] = name.strip()
            st.rerun()
        st.error("Sign-in refused: a name and the dashboard's access token are needed.")
    st.stop()
