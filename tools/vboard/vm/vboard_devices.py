def setup(board):
    pass
