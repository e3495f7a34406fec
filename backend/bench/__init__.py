"""What the API serves from the bench: the simulated preview of a table or an envelope, and its safety figures."""
