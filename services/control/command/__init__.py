"""The networked command side: response model, commands in flight, sequences, the link."""
