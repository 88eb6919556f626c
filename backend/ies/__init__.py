"""IES LM-63 photometry: reader (lm63), Cycles-compatible profile (profile), light (light), CLI (cli)."""
