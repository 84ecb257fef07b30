//! What the protocol travels over: one byte stream for every connection,
//! whether plain TCP, TLS over it, or a test's in-memory pipe, so the Guest
//! and the Host (and the Media between them) hold any of them alike.

use tokio::io::{AsyncRead, AsyncWrite};

/// A connection's byte stream: plain TCP, or TLS over it.
pub trait Io: AsyncRead + AsyncWrite + Unpin + Send {}

impl<T: AsyncRead + AsyncWrite + Unpin + Send> Io for T {}
