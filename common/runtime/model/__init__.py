"""The pure scheduling model: core contract, declared dataflow, Host, record, inproc runtime."""
