"""One table type and one CSV format (material.table) for element results, FE histories, DEM runs, sweeps."""

import numpy as np
import pytest

from material.table import Table, TableWriter, read_table


def test_a_table_reads_back_to_the_bit_with_its_descriptions_and_metadata(tmp_path):
    rng = np.random.default_rng(7)
    t = Table({"x": rng.normal(size=5), "q_kPa": rng.normal(size=5) * 1e3}, {"q_kPa": "deviator [kPa], compression +"},
              {"test": "triaxial", "p0_kPa": 100.0}, title="example", convention="compression positive")
    back = read_table(t.write_csv(tmp_path / "t.csv"))
    assert back.columns == ["x", "q_kPa"] and back.title == "example" and back.convention == "compression positive"
    np.testing.assert_array_equal(back["q_kPa"], t["q_kPa"])
    assert back.descriptions == {"q_kPa": "deviator [kPa], compression +"} and back.metadata["p0_kPa"] == 100.0


def test_rows_appended_fill_missing_columns_with_nan():
    t = Table()
    t.append({"step": 0, "a": 1.0})
    t.append({"step": 1, "b": 2.0})
    assert len(t) == 2 and t.columns == ["step", "a", "b"]
    assert t["a"][0] == 1.0 and np.isnan(t["a"][1]) and np.isnan(t["b"][0])
    with pytest.raises(KeyError, match="no column 'c'; available"):
        t["c"]
    with pytest.raises(ValueError, match="column 'd': expected shape"):
        t.add_column("d", [1.0])


def test_the_row_writer_writes_the_same_format_and_appends_after_a_restart(tmp_path):
    path = tmp_path / "h.csv"
    w = TableWriter(path, title="log", descriptions={"r": "residual [-]"})
    for k in range(3):
        w.write({"k": k, "r": 10.0 ** -k})
    w.close()
    w = TableWriter(path, title="log", append=True)
    w.write({"k": 3, "r": 1e-3})
    w.close()
    back = read_table(path)
    assert list(back["k"]) == [0, 1, 2, 3] and back.descriptions == {"r": "residual [-]"}
    path.write_text(path.read_text() + "4,x\n")
    with pytest.raises(ValueError, match="data row 5 holds a value that is not a number"):
        read_table(path)


def test_every_result_is_a_table():
    from dem.experiments import Run
    from femgran.solver import History
    from material.results import ElementResult

    assert issubclass(ElementResult, Table) and issubclass(History, Table)
    assert Run.__dataclass_fields__["history"].type in ("Table", Table)
