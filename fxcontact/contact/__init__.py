"""Nodal penalty contact: contact boundary, schemes, penalty kernels."""
