"""Who may do what, and what is kept secret: API keys checked, their scopes and cells
(auth), controller passwords encrypted at rest (secretbox).
"""
