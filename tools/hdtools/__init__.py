"""Host tools of the hdjoint project (Python front ends over the C code)."""
