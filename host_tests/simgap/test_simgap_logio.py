import numpy as np
import pytest

from tools.simgap.logio import LogError, read_log

HEAD = "time_s,temp_c,out_x,out_y,out_z,ref_x,ref_y,ref_z"


def rows(n, extra=""):
    return "\n".join(f"{i},{20 + i * 0.1},{i},{2 * i},{3 * i},0,0,1{extra}" for i in range(n))


def test_reads_metadata_columns_and_ignores_unknown():
    text = ("# sensor: accel\n# ref_unit: g\n# out_unit: LSB\n"
            + HEAD + ",supply_v,note\n" + rows(12, ",3.3,hello") + "\n\n")
    log = read_log("x.csv", text)
    assert log.meta == {"sensor": "accel", "ref_unit": "g", "out_unit": "LSB"}
    assert len(log) == 12
    assert log.out[5].tolist() == [5, 10, 15]
    assert log.ref[0].tolist() == [0, 0, 1]
    assert np.allclose(log.supply, 3.3)
    assert log.acc is None and log.run is None
    assert log.temp[3] == pytest.approx(20.3)


def test_bad_cell_names_line_and_column():
    lines = [HEAD] + rows(12).split("\n")
    lines[6] = "5,20.5,5,abc,15,0,0,1"       # data row 5 is file line 7 (after the header)
    with pytest.raises(LogError, match=r"line 7, column 4 \(out_y\): not a number: 'abc'"):
        read_log("bad.csv", "\n".join(lines))


def test_line_numbers_count_metadata_lines():
    lines = ["# sensor: gyro", HEAD] + rows(12).split("\n")
    lines[3] = "1,nan,1,2,3,0,0,1"
    with pytest.raises(LogError, match=r"line 4, column 2 \(temp_c\): not a finite number"):
        read_log("bad.csv", "\n".join(lines))


def test_missing_required_column_is_named():
    text = HEAD.replace(",ref_y", "") + "\n" + "\n".join("1,2,3,4,5,6,7" for _ in range(12))
    with pytest.raises(LogError, match="lacks required column.*ref_y"):
        read_log("m.csv", text)


def test_short_row_names_its_line():
    lines = [HEAD] + rows(12).split("\n")
    lines[4] = "3,20,1,2"
    with pytest.raises(LogError, match="line 5: 4 fields, header has 8"):
        read_log("s.csv", "\n".join(lines))


def test_time_going_back_needs_a_run_column():
    lines = [HEAD] + rows(12).split("\n")
    lines[8] = "0,20,1,2,3,0,0,1"
    with pytest.raises(LogError, match="line 9, column 1 \\(time_s\\): time goes backwards"):
        read_log("t.csv", "\n".join(lines))


def test_runs_numbered_in_order_of_appearance():
    body = "\n".join(f"{i % 6},{20},{i},{i},{i},0,0,0,{r}"
                     for i, r in enumerate([7] * 6 + [3] * 6 + [9] * 6))
    log = read_log("r.csv", HEAD + ",run\n" + body)
    assert log.run.tolist() == [0] * 6 + [1] * 6 + [2] * 6


def test_partial_acc_columns_rejected():
    with pytest.raises(LogError, match="acc_x, acc_y, acc_z must come together"):
        read_log("a.csv", HEAD + ",acc_x\n" + rows(12, ",0.5"))


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(LogError, match="cannot read"):
        read_log(tmp_path / "nope.csv")
