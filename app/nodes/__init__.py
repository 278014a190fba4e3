"""Several machines as one site (issue 31, docs/scaling.md): nodes sharing one PostgreSQL
database place the cameras among themselves by lease (``leases``), and each runs the
cameras it holds (``keeper``)."""
