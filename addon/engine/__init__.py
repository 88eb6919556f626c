"""The LAMINA render engine and the backend child-process job."""
